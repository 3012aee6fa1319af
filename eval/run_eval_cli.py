"""``lts eval RUN [--gt GT] [--lpips-weights PATH] [--test-views SCENE]``: evaluate a training run
(``RUN`` and ``GT`` as :mod:`eval.run_inputs` resolves them), write ``eval.json`` and ``report.html``
in the run folder (mounted through :func:`eval.mesh_eval_cli.eval_command`); on another scene's
held-out views (:mod:`eval.shared_views`) print the metrics and write nothing."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from rig.cli_support import console, emit_json
from rig.native_output import native_output_to_stderr

if TYPE_CHECKING:
    from eval.run_eval import RunEvaluation


def _text(value, unit: str = "", scale: float = 1.0, digits: int = 3) -> str:
    return "n/a" if value is None else f"{value * scale:.{digits}f}{unit}"


def evaluate_run_command(
    run_dir: Path,
    gt: Path | None,
    threshold: float,
    samples: int,
    report: bool,
    physics: bool,
    device: str,
    lpips_weights: Path | None,
    json_out: bool,
    seams: Path | None = None,
    test_views: Path | None = None,
) -> None:
    from eval.run_eval import evaluate_run
    from eval.run_inputs import resolve_run_inputs
    from eval.shared_views import views_scene

    inputs = resolve_run_inputs(run_dir, gt)
    other = None if test_views is None else views_scene(test_views)

    def log(message: str) -> None:
        console.print(f"[dim]{message}[/]", highlight=False)

    with native_output_to_stderr():
        evaluation = evaluate_run(
            inputs.run_dir, inputs.gt, threshold, samples, device, physics, log, lpips_weights=lpips_weights,
            seams=seams, test_views=other,
        )  # fmt: skip
        written = [] if other is not None else _write(evaluation, report, log)  # the run's own views only
    m = evaluation.metrics
    if json_out:
        emit_json(m)
        return
    psnr, ssim, lpips = _text(m["psnr"], " dB", digits=2), _text(m["ssim"]), _text(m["lpips"])
    depth = _text(m["depth_error_median_m"], " cm", 100, 2)
    holes = _text(m["hole_fraction_leaned"], " %", 100, 2)
    views = "test views" if other is None else f"held-out views of {other.root}"
    lines = [
        f"{views} ({m['n_test_views']}): PSNR {psnr} (each view's colours fitted to its image: "
        f"{_text(m['psnr_color_aligned'], ' dB', digits=2)}; with hard triangle edges: "
        f"{_text(m['psnr_hard_edges'], ' dB', digits=2)}), SSIM {ssim}, LPIPS {lpips}; "
        f"LiDAR depth error median {depth}",
        f"geometry at {m['threshold_m']:g} m: F-score {_text(m['fscore'])} (visible GT "
        f"{_text(m['fscore_visible'])}), Chamfer-L1 {_text(m['chamfer_m'], ' cm', 100, 2)}; sample to "
        f"surface: F-score {_text(m['fscore_surface'])} (visible GT {_text(m['fscore_visible_surface'])}), "
        f"Chamfer-L1 {_text(m['chamfer_surface_m'], ' cm', 100, 2)}",
        f"against the test keyframes' LiDAR at {_text(m['lidar_threshold_m'], ' m', digits=2)}: F-score "
        f"{_text(m['lidar_fscore'])} (precision {_text(m['lidar_precision'])}, recall "
        f"{_text(m['lidar_recall'])}), median distance {_text(m['lidar_distance_median_m'], ' cm', 100, 1)}",
        f"leaned-view holes {holes} (against the {m['hole_reference']}); physics fall-through "
        f"{_text(m['fall_through_rate'], ' %', 100, 1)}, height error mean "
        f"{_text(m['height_error_mean_m'], ' cm', 100, 2)}",
        f"{m['n_triangles']} triangles, trained in {_text(m['train_seconds'], ' s', digits=0)}",
    ]
    if m["psnr_static"] is not None or m["mover_swept_area_fraction"] is not None:
        lines.append(
            f"moving objects: PSNR on the static pixels {_text(m['psnr_static'], ' dB', digits=2)} "
            f"({_text(m['moving_pixel_fraction'], ' %', 100, 1)} of the pixels show one); mesh area "
            f"inside their swept volumes {_text(m['mover_swept_area_fraction'], ' %', 100, 2)}"
        )
    if m["psnr_sky"] is not None:
        lines.append(
            f"sky (the pixels the ground truth leaves empty): PSNR {_text(m['psnr_sky'], ' dB', digits=2)}, "
            f"{_text(m['sky_covered_fraction'], ' %', 100, 1)} of them covered by triangles"
        )
    if m["seam_views"] is not None:
        at_seams, elsewhere = (
            _text(m["seam_hole_fraction"], " %", 100, 2),
            _text(m["off_seam_hole_fraction"], " %", 100, 2),
        )
        lines.append(
            f"seams of {m['seam_blocks']} blocks: leaned-view holes {at_seams} at them, {elsewhere} "
            f"elsewhere in the same {m['seam_views']} views; physics fall-through "
            f"{_text(m['seam_fall_through_rate'], ' %', 100, 1)} of {m['seam_physics_probes']} probes "
            "across them"
        )
    for line in lines:
        console.print(line, highlight=False)
    by_reason: dict[str, list[str]] = {}
    for key, reason in m["reasons"].items():
        by_reason.setdefault(reason, []).append(key)
    for reason, keys in by_reason.items():
        console.print(f"  [dim]null: {', '.join(keys)}: {reason}[/]", highlight=False)
    if written:
        console.print(f"wrote {' and '.join(map(str, written))}", highlight=False)


def _write(evaluation: RunEvaluation, report: bool, log: Callable[[str], None]) -> list[Path]:
    """Write ``eval.json`` and, with ``report``, ``report.html`` in the run folder; their paths."""
    from eval.run_eval import write_eval_json

    written = [write_eval_json(evaluation)]
    if report:
        from eval.report import write_report

        log("writing the report")
        written.append(write_report(evaluation))
    return written
