"""``lts bench raster``: benchmarks owned by the splat package (mounted by eval/cli.py)."""

from __future__ import annotations

import typer

from rig.cli_support import console, emit_json

bench_app = typer.Typer(name="bench", help="Benchmarks (timings and memory).", no_args_is_help=True)


@bench_app.command("raster")
def bench_raster(
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object on stdout."),
    triangles: list[int] = typer.Option([20_000, 100_000], "--triangles", "-n", help="Scene sizes."),
    width: int = typer.Option(320, help="Image width in pixels."),
    height: int = typer.Option(240, help="Image height in pixels."),
    repeats: int = typer.Option(5, min=1, help="Timed runs per row (median; one warm-up first)."),
) -> None:
    """Forward+backward time and peak memory of every available rasteriser backend."""
    from splat.raster.bench import BenchRow, available_backends, run_bench

    backends = available_backends()
    console.print(f"backends: {', '.join(backends)}; {width}x{height}, 2-20 px triangles", highlight=False)

    def report(row: BenchRow) -> None:
        console.print(
            f"  {row.backend:<10} {row.n_triangles:>7} triangles  {row.ms_fwd_bwd:9.1f} ms  "
            f"{row.peak_mb:8.1f} MB",
            highlight=False,
        )

    result = run_bench(triangles, width, height, repeats, backends, report)
    for backend, x in result["speedup_vs_reference"].items():
        console.print(f"  {backend}: {x:.1f}x faster than the reference", highlight=False)
    if json_out:
        emit_json(result)
