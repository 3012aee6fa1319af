"""``lts weights download``: fetch the LPIPS weights ``lts eval`` needs, checked by SHA-256
(:mod:`eval.lpips_weights`)."""

from __future__ import annotations

from pathlib import Path

import typer

from rig.cli_support import HELP_MARKUP, console, output_file_option

app = typer.Typer(
    rich_markup_mode=HELP_MARKUP,
    help="Weights the evaluation uses: LPIPS (AlexNet trunk + v0.1 heads). Needs internet once.",
    no_args_is_help=True,
)


@app.command("download")
def download_command(
    out: Path | None = output_file_option(
        None,
        "--out",
        help="File to write (default: the cache lts eval reads, ~/.cache/lidar-ts/lpips_alex.pt).",
    ),
    force: bool = typer.Option(False, "--force", help="Fetch again even when the file is there."),
) -> None:
    """Fetch the LPIPS weights (SHA-256 checked) into one file lts eval reads.

    torchvision's AlexNet (244 MB) and the LPIPS v0.1 alex heads are checked by size and SHA-256 and
    written as one 10 MB weights file. Copies already in the torch hub cache or the lpips package
    are used when their checksums match.
    """
    from eval.lpips_weights import cache_path, download_weights

    target = out if out is not None else cache_path()
    if target.exists() and not force:
        console.print(f"{target} is already there (--force to fetch it again)", highlight=False)
        return
    written = download_weights(target, log=lambda message: console.print(message, highlight=False))
    console.print(f"wrote {written}; lts eval reports LPIPS with it", highlight=False)
