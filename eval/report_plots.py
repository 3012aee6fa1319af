"""Pictures for the run report: PNG bytes from numpy images and matplotlib figures (Agg backend)."""

from __future__ import annotations

import io

import cv2
import numpy as np

from rig.transforms import transform_points

HOLE_RED = np.array([0.93, 0.11, 0.14])
MISSED_COLOUR = "#7b2cbf"
#: Colour map of distances and errors (perceptually uniform, dark = good).
ERROR_CMAP = "inferno"
DISTANCE_CMAP = "RdYlGn_r"


def _pyplot():
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    plt.rcParams.update(
        {
            "font.size": 9,
            "axes.titlesize": 10,
            "axes.spines.top": False,
            "axes.spines.right": False,
            "axes.grid": True,
            "grid.alpha": 0.3,
            "figure.dpi": 110,
        }
    )
    return plt


def png(image: np.ndarray) -> bytes:
    """PNG bytes of an ``(H, W, 3)`` RGB image (float in [0, 1] or uint8)."""
    if image.dtype != np.uint8:
        image = (np.clip(image, 0, 1) * 255 + 0.5).astype(np.uint8)
    ok, data = cv2.imencode(".png", cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
    if not ok:
        raise RuntimeError("PNG encoding failed")
    return data.tobytes()


def figure_png(fig) -> bytes:
    plt = _pyplot()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", bbox_inches="tight", facecolor="white")
    plt.close(fig)
    return buffer.getvalue()


def colormap(values: np.ndarray, vmax: float, cmap: str = ERROR_CMAP) -> np.ndarray:
    """``(..., 3)`` RGB of ``values`` scaled to ``[0, vmax]`` by a matplotlib colour map."""
    from matplotlib import colormaps

    return colormaps[cmap](np.clip(values / vmax, 0, 1))[..., :3]


def error_heatmap(render: np.ndarray, target: np.ndarray, vmax: float) -> np.ndarray:
    """Per-pixel mean absolute RGB error as an ``(H, W, 3)`` heat map (``vmax`` = brightest)."""
    return colormap(np.abs(render - target).mean(axis=-1), vmax)


def hole_overlay(render: np.ndarray, holes: np.ndarray, surface: np.ndarray | None = None) -> np.ndarray:
    """The render with holes painted red (and, if given, pixels without reference surface dimmed)."""
    image = render.copy()
    if surface is not None:
        image[~surface] *= 0.35
    image[holes] = 0.25 * image[holes] + 0.75 * HOLE_RED
    return image


def colorbar(vmax: float, label: str, cmap: str = ERROR_CMAP) -> bytes:
    """A thin horizontal colour bar from 0 to ``vmax``."""
    plt = _pyplot()
    from matplotlib import cm, colors

    fig, ax = plt.subplots(figsize=(4.2, 0.55))
    fig.colorbar(
        cm.ScalarMappable(colors.Normalize(0, vmax), cmap), cax=ax, orientation="horizontal", label=label
    )
    return figure_png(fig)


def _subsample(count: int, limit: int, seed: int = 0) -> np.ndarray:
    if count <= limit:
        return np.arange(count)
    return np.sort(np.random.default_rng(seed).choice(count, limit, replace=False))


def _below_ceiling(gt: np.ndarray) -> float:
    """A height that cuts the ceiling off a top-down picture (75 % of the GT's height range)."""
    floor, top = np.percentile(gt[:, 2], [1, 99])
    return float(floor + 0.75 * (top - floor))


def point_cloud_figure(points, max_points: int = 50_000) -> bytes:
    """Two top-down pictures (ceiling cut away) of the frustum-culled samples: the reconstruction's
    coloured by distance to the ground truth (precision) and the ground truth's, found or missed
    (recall)."""
    plt = _pyplot()
    from matplotlib import cm, colors

    rec = transform_points(points.T_display_world, points.reconstructed)
    gt = transform_points(points.T_display_world, points.ground_truth)
    cut = _below_ceiling(gt)
    missed = points.to_reconstruction >= points.threshold_m
    norm = colors.Normalize(0, 2 * points.threshold_m)
    limits = np.percentile(np.vstack([rec[:, :2], gt[:, :2]]), [0.2, 99.8], axis=0)
    pad = 0.05 * (limits[1] - limits[0]).max()

    fig, axes = plt.subplots(1, 2, figsize=(12, 5.6), sharex=True, sharey=True)
    keep = np.flatnonzero(rec[:, 2] < cut)
    keep = keep[_subsample(len(keep), max_points)]
    order = keep[np.argsort(points.to_ground_truth[keep])]  # worst points drawn last
    axes[0].scatter(
        rec[order, 0], rec[order, 1], s=1.0, c=points.to_ground_truth[order], cmap=DISTANCE_CMAP, norm=norm,
        linewidths=0, rasterized=True,
    )  # fmt: skip
    axes[0].set_title("reconstruction, coloured by distance to ground truth (precision)")
    keep = np.flatnonzero(gt[:, 2] < cut)
    keep = keep[_subsample(len(keep), max_points, 1)]
    found, lost = keep[~missed[keep]], keep[missed[keep]]
    axes[1].scatter(gt[found, 0], gt[found, 1], s=1.0, c="#9aa5b8", linewidths=0, rasterized=True)
    axes[1].scatter(gt[lost, 0], gt[lost, 1], s=1.6, c=MISSED_COLOUR, linewidths=0, rasterized=True)
    axes[1].set_title("ground truth: found (grey) or missed (violet) (recall)")
    for ax in axes:
        ax.set_aspect("equal")
        ax.set_xlim(limits[0, 0] - pad, limits[1, 0] + pad)
        ax.set_ylim(limits[0, 1] - pad, limits[1, 1] + pad)
        ax.set_xlabel("x (m)")
        ax.grid(False)
    axes[0].set_ylabel("y (m)")
    fig.colorbar(
        cm.ScalarMappable(norm, DISTANCE_CMAP), ax=axes[0], orientation="horizontal", fraction=0.05, pad=0.1,
        label="distance to ground truth (m)",
    )  # fmt: skip
    axes[1].text(
        0.0, -0.16, f"missed: farther than {points.threshold_m:g} m from the reconstruction; points less "
        f"than {cut - np.percentile(gt[:, 2], 1):.1f} m above the floor", transform=axes[1].transAxes,
        fontsize=8, color="#555", va="top",
    )  # fmt: skip
    return figure_png(fig)


def training_curves(rows: list[dict]) -> bytes | None:
    """Loss terms, test PSNR and triangle count against iteration (``None`` without rows)."""
    rows = [r for r in rows if "iteration" in r]
    if not rows:
        return None
    plt = _pyplot()
    it = np.array([r["iteration"] for r in rows])
    fig, axes = plt.subplots(1, 3, figsize=(12.5, 3.4))
    terms = sorted({k for r in rows for k in (r.get("loss") or {})}, key=lambda k: (k != "total", k))
    for term in terms:
        values = np.array([(r.get("loss") or {}).get(term, np.nan) for r in rows], dtype=float)
        if np.any(values > 0):
            axes[0].plot(it, values, marker=".", lw=2.0 if term == "total" else 1.2, label=term)
    axes[0].set_yscale("log")
    axes[0].set_title("loss terms (log scale)")
    axes[0].legend(fontsize=7, ncol=4, loc="upper center", bbox_to_anchor=(0.5, -0.2), frameon=False)
    for key, label in (("test_psnr", "test PSNR (dB)"),):
        values = np.array([r.get(key, np.nan) for r in rows], dtype=float)
        axes[1].plot(it, values, marker="o", color="#1f77b4")
        axes[1].set_title(label)
    if any("test_ssim" in r for r in rows):
        twin = axes[1].twinx()
        twin.plot(it, [r.get("test_ssim", np.nan) for r in rows], marker=".", color="#ff7f0e", lw=1)
        twin.set_ylabel("test SSIM", color="#ff7f0e")
        twin.grid(False)
    axes[2].plot(it, [r.get("n_triangles", np.nan) for r in rows], marker="o", color="#2ca02c")
    axes[2].set_title("triangles")
    for ax in axes:
        ax.set_xlabel("iteration")
    fig.tight_layout()
    return figure_png(fig)


def physics_figure(drops, background=None) -> bytes:
    """Top-down map of the probes — resting-height error (colour), fall-throughs (red crosses) —
    over ``background`` ground-truth points ``(N, 3)`` (optional), and a histogram of the signed
    height error."""
    plt = _pyplot()
    start = transform_points(drops.T_display_world, drops.start)
    valid = ~drops.gt_fell
    fell = valid & drops.rec_fell
    rested = valid & ~drops.rec_fell
    signed = drops.rec_height - drops.gt_height
    fig, (ax, hist) = plt.subplots(1, 2, figsize=(12, 4.8), gridspec_kw={"width_ratios": [1.5, 1]})
    if background is not None and len(background):
        bg = transform_points(drops.T_display_world, background)
        bg = bg[bg[:, 2] < _below_ceiling(bg)]
        bg = bg[_subsample(len(bg), 40_000, 2)]
        ax.scatter(bg[:, 0], bg[:, 1], s=0.6, c="#c9ced8", linewidths=0, rasterized=True)
    vmax = max(0.05, float(np.abs(signed[rested]).max()) if rested.any() else 0.05)
    sc = ax.scatter(
        start[rested, 0], start[rested, 1], c=np.abs(signed[rested]), cmap="viridis", vmin=0, vmax=vmax,
        s=40, edgecolors="k", linewidths=0.4, label="rested",
    )  # fmt: skip
    ax.scatter(start[fell, 0], start[fell, 1], marker="x", c="red", s=60, linewidths=2, label="fell through")
    if (~valid).any():
        ax.scatter(
            start[~valid, 0], start[~valid, 1], marker="o", facecolors="none", edgecolors="#888", s=30,
            label="fell through the ground truth (ignored)",
        )  # fmt: skip
    fig.colorbar(sc, ax=ax, label="|resting height error| (m)", shrink=0.85)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=3, frameon=False)
    ax.set_title("probes along the keyframe footprint (top-down)")
    ax.grid(False)
    if rested.any():
        hist.hist(100 * signed[rested], bins="auto", color="#3557d4", alpha=0.85)
    hist.axvline(0, color="k", lw=0.8)
    hist.set_xlabel("resting height − ground-truth resting height (cm)")
    hist.set_ylabel("probes")
    hist.set_title("signed height error of the probes that rested")
    fig.tight_layout()
    return figure_png(fig)
