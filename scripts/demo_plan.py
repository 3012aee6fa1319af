"""Say what `make demo` will do, and which of its stages exist in this checkout.

`make demo` runs `lts demo` once that command exists; until then it runs this script instead,
which reports the pipeline honestly rather than faking a result.
"""

from __future__ import annotations

import typer.main

from eval.cli import app

STAGES = [
    ("sim", "create a virtual-rig scene with ground truth (rig/sim)"),
    ("calibrate", "calibrate intrinsics, LiDAR-camera extrinsic and time offset (calib)"),
    ("slam", "import mesh-SLAM output or run the fallback mapper (slam_bridge)"),
    ("prepare", "build keyframes: undistorted images, poses, LiDAR depth, normal priors (slam_bridge)"),
    ("train", "LiDAR-guided coarse-to-fine triangle splatting and mesh export (splat)"),
    ("eval", "metrics vs ground truth (so far only `lts eval --mesh`; RUN_DIR and report.html to come)"),
    ("reconstruct", "all of the above on one session, resumable (end to end)"),
    ("demo", "record a virtual-rig scene through the mock devices and reconstruct it"),
]


def main() -> None:
    available = set(typer.main.get_command(app).commands)
    print("`lts demo` is not built yet, so `make demo` cannot run the pipeline. Once it lands, it will:")
    for name, what in STAGES:
        mark = "available" if name in available else "not built yet"
        print(f"  lts {name:<12} {what}  [{mark}]")
    print(f"Commands available now: {', '.join(sorted(available))}. See `lts --help`.")


if __name__ == "__main__":
    main()
