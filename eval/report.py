"""``RUN_DIR/report.html``: one self-contained page (images embedded as base64 PNG, no external
resources) with the metric table, test-view triptychs, leaned-view holes, the F-score-coloured
point cloud, the training curves, the physics test and the run's configuration."""

from __future__ import annotations

import base64
import datetime as _dt
import html
import json
from pathlib import Path

import numpy as np
import yaml

from eval import report_plots as plots
from eval.run_eval import RunEvaluation
from splat import run_dir as layout

REPORT_FILE = "report.html"
#: Mean absolute RGB error shown as the brightest colour of the heat maps (same for every run).
HEATMAP_MAX = 0.2

#: Section ids and headings, in page order (tests check that each is present).
SECTIONS = {
    "metrics": "Metrics",
    "test-views": "Test views",
    "leaned-views": "Leaned views",
    "geometry": "Geometry",
    "training": "Training curves",
    "physics": "Physics",
    "configuration": "Configuration",
}

# (key, label, kind); kinds: db, ratio, pct, m (shown in cm), s, px, int, text
_GROUPS = {
    "Photometry (held-out views)": [
        ("psnr", "PSNR", "db"),
        ("psnr_sharp", "PSNR without the camera's blur", "db"),
        ("camera_blur_px", "camera's blur (Gaussian σ, fitted on the training views)", "px"),
        ("psnr_color_aligned", "PSNR, each view's colours fitted (exposure)", "db"),
        ("psnr_hard_edges", "PSNR with hard triangle edges (as a mesh rasteriser draws them)", "db"),
        ("ssim", "SSIM", "ratio"),
        ("lpips", "LPIPS", "ratio"),
        ("depth_error_median_m", "LiDAR depth error, median", "m"),
        ("depth_error_mean_m", "LiDAR depth error, mean", "m"),
        ("depth_error_pixels", "LiDAR pixels compared", "int"),
    ],
    "Geometry (frustum-culled)": [
        ("fscore", "F-score", "ratio"),
        ("precision", "precision", "ratio"),
        ("recall", "recall", "ratio"),
        ("chamfer_m", "Chamfer-L1", "m"),
        ("accuracy_m", "accuracy (rec → GT)", "m"),
        ("completeness_m", "completeness (GT → rec)", "m"),
        ("threshold_m", "threshold", "m"),
    ],
    "Geometry (GT the training cameras see)": [
        ("fscore_visible", "F-score", "ratio"),
        ("precision_visible", "precision", "ratio"),
        ("recall_visible", "recall", "ratio"),
        ("chamfer_visible_m", "Chamfer-L1", "m"),
        ("accuracy_visible_m", "accuracy (rec → GT)", "m"),
        ("completeness_visible_m", "completeness (GT → rec)", "m"),
        ("gt_visible_fraction", "visible share of culled GT", "pct"),
    ],
    "Holes (alpha < 0.5 where the reference has a surface)": [
        ("hole_fraction_leaned", "leaned views", "pct"),
        ("hole_fraction_test", "test views", "pct"),
        ("hole_reference", "reference", "text"),
        ("n_leaned_views", "leaned views rendered", "int"),
    ],
    "Physics (probes dropped on the collision mesh)": [
        ("fall_through_rate", "fall-through rate", "pct"),
        ("height_error_mean_m", "resting-height error, mean", "m"),
        ("height_error_max_m", "resting-height error, max", "m"),
        ("physics_probes", "probes resting on GT", "int"),
        ("physics_mesh", "mesh", "text"),
    ],
    "Run": [
        ("method", "method", "text"),
        ("n_triangles", "triangles", "int"),
        ("train_seconds", "training time", "s"),
        ("n_test_views", "test views", "int"),
        ("gt_alignment_rmse_m", "GT alignment RMSE (poses)", "m"),
    ],
}
_HEADLINE = [
    ("psnr", "PSNR", "db"),
    ("ssim", "SSIM", "ratio"),
    ("fscore", "F-score", "ratio"),
    ("chamfer_m", "Chamfer-L1", "m"),
    ("hole_fraction_leaned", "leaned holes", "pct"),
    ("fall_through_rate", "fall-through", "pct"),
    ("n_triangles", "triangles", "int"),
]
_NOT_SHOWN = {"reasons", "run_dir", "scene_dir", "gt_dir"}

_CSS = """
:root { --fg:#1d2330; --muted:#6b7385; --line:#e3e6ee; --bg:#f5f6fa; --card:#fff; --accent:#3557d4; }
* { box-sizing: border-box; }
body { margin:0; background:var(--bg); color:var(--fg);
  font: 14px/1.45 system-ui, -apple-system, "Segoe UI", Roboto, "Helvetica Neue", Arial, sans-serif; }
header { background:#1d2330; color:#fff; padding:22px 32px 18px; }
header h1 { margin:0 0 4px; font-size:22px; font-weight:600; }
header .sub { color:#b9c0d4; font-size:13px; }
nav { background:#fff; border-bottom:1px solid var(--line); padding:8px 32px;
  position:sticky; top:0; z-index:2; }
nav a { color:var(--accent); text-decoration:none; margin-right:18px; font-size:13px; }
main { max-width:1240px; margin:0 auto; padding:8px 32px 40px; }
section { background:var(--card); border:1px solid var(--line); border-radius:10px; padding:18px 22px;
  margin:18px 0; }
h2 { margin:0 0 12px; font-size:18px; font-weight:600; }
h3 { margin:14px 0 6px; font-size:14px; font-weight:600; }
p.note { color:var(--muted); margin:4px 0 10px; font-size:13px; }
.tiles { display:flex; flex-wrap:wrap; gap:10px; margin-bottom:14px; }
.tile { flex:1 1 120px; border:1px solid var(--line); border-radius:8px; padding:8px 12px;
  background:#fafbfd; }
.tile .v { font-size:21px; font-weight:600; }
.tile .k { color:var(--muted); font-size:12px; }
.groups { display:grid; grid-template-columns:repeat(auto-fill, minmax(360px, 1fr)); gap:14px; }
table { border-collapse:collapse; width:100%; font-size:13px; }
th, td { text-align:left; padding:4px 8px; border-bottom:1px solid var(--line); vertical-align:top; }
th { font-weight:600; color:var(--muted); font-size:12px; }
td.v { text-align:right; font-variant-numeric:tabular-nums; white-space:nowrap; }
td code, li code { font-size:11px; color:var(--muted); }
.na { color:var(--muted); }
.why { display:block; color:var(--muted); font-size:11px; white-space:normal; text-align:right; }
.row { display:flex; flex-wrap:wrap; gap:10px; align-items:flex-start; margin-bottom:12px; }
figure { margin:0; }
figure img { display:block; width:100%; border-radius:4px; border:1px solid var(--line); }
figcaption { color:var(--muted); font-size:12px; margin-top:3px; }
.trip figure { flex:1 1 0; min-width:220px; }
.lean figure { flex:1 1 0; min-width:180px; }
.wide img { max-width:100%; width:auto; border:none; }
.config { columns:3 260px; font-size:12px; }
.config div { break-inside:avoid; padding:1px 0; border-bottom:1px dotted var(--line); }
.config b { font-weight:500; color:var(--muted); }
ul.skips { margin:4px 0; padding-left:20px; font-size:13px; }
footer { color:var(--muted); font-size:12px; text-align:center; padding:0 0 24px; }
"""


def _img(data: bytes, alt: str) -> str:
    encoded = base64.b64encode(data).decode("ascii")
    return f'<img src="data:image/png;base64,{encoded}" alt="{html.escape(alt)}">'


def _figure(data: bytes, alt: str, caption: str = "", wide: bool = False) -> str:
    text = f"<figcaption>{html.escape(caption)}</figcaption>" if caption else ""
    opening = '<figure class="wide">' if wide else "<figure>"
    return f"{opening}{_img(data, alt)}{text}</figure>"


def _format(value, kind: str) -> str:
    if value is None or (isinstance(value, float) and not np.isfinite(value)):
        return "—"
    if kind == "db":
        return f"{value:.2f} dB"
    if kind == "ratio":
        return f"{value:.4f}"
    if kind == "pct":
        return f"{100 * value:.2f} %"
    if kind == "m":
        return f"{100 * value:.2f} cm"
    if kind == "s":
        return f"{value:.1f} s"
    if kind == "px":
        return f"{value:.2f} px"
    if kind == "int":
        return f"{int(value):,}".replace(",", " ")
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


def _reason(metrics: dict, key: str) -> str:
    reasons = metrics.get("reasons") or {}
    if key in reasons:
        return reasons[key]
    if key.startswith(("physics", "fall_through", "height_error")):
        return reasons.get("physics", "")
    return ""


def _metric_tables(metrics: dict) -> str:
    tiles = "".join(
        f'<div class="tile"><div class="v">{_format(metrics.get(k), kind)}</div>'
        f'<div class="k">{label}</div></div>'
        for k, label, kind in _HEADLINE
    )
    known = {key for rows in _GROUPS.values() for key, _, _ in rows} | _NOT_SHOWN
    extra = [(k, k, "text") for k in metrics if k not in known]
    groups = []
    for title, rows in [*_GROUPS.items(), *([("Other", extra)] if extra else [])]:
        missing = [_reason(metrics, key) for key, _, _ in rows if metrics.get(key) is None]
        reasons = set(missing) - {""}
        # one reason for several missing values is said once, under the heading
        shared = next(iter(reasons)) if len(missing) >= 2 and len(reasons) == 1 else ""
        body = []
        for key, label, kind in rows:
            value = metrics.get(key)
            cell = html.escape(_format(value, kind))
            if value is None:
                why = "" if shared else _reason(metrics, key)
                cell = f'<span class="na">{cell}</span>' + (
                    f'<span class="why">{html.escape(why)}</span>' if why else ""
                )
            body.append(f"<tr><td>{html.escape(label)} <code>{key}</code></td><td class='v'>{cell}</td></tr>")
        note = f'<p class="note">— {html.escape(shared)}</p>' if shared else ""
        groups.append(
            f"<div><h3>{html.escape(title)}</h3>{note}<table><tbody>{''.join(body)}</tbody></table></div>"
        )
    return f'<div class="tiles">{tiles}</div><div class="groups">{"".join(groups)}</div>'


def _test_views(evaluation: RunEvaluation) -> str:
    if not evaluation.views:
        return '<p class="note">No test views.</p>'
    parts = [
        '<p class="note">Each held-out keyframe: the final model\'s render, the captured image, and the '
        f"per-pixel mean absolute RGB error (colour scale 0 – {HEATMAP_MAX:g}).</p>",
        _figure(plots.colorbar(HEATMAP_MAX, "mean |render − image|"), "colour scale", wide=True),
    ]
    for view in evaluation.views:
        heat = plots.error_heatmap(view.render, view.target, HEATMAP_MAX)
        name = html.escape(view.name)
        parts.append(
            f"<h3>{name} <span class='na'>PSNR {view.psnr:.2f} dB · SSIM {view.ssim:.4f}</span></h3>"
            '<div class="row trip">'
            + _figure(plots.png(view.render), f"render {view.name}", "render")
            + _figure(plots.png(view.target), f"ground truth {view.name}", "ground truth (captured image)")
            + _figure(plots.png(heat), f"error {view.name}", "error heat map")
            + "</div>"
        )
    return "".join(parts)


def _leaned_views(evaluation: RunEvaluation) -> str:
    metrics = evaluation.metrics
    if not evaluation.leaned:
        why = _reason(metrics, "hole_fraction_leaned") or "no reference surface to measure holes against"
        return f'<p class="note">Not computed: {html.escape(why)}.</p>'
    reference = {"ground_truth": "the ground-truth mesh", "slam_mesh": "the scene's SLAM mesh (no --gt)"}.get(
        metrics.get("hole_reference"), str(metrics.get("hole_reference"))
    )
    parts = [
        '<p class="note">Each test pose turned ±10° and shifted ±0.2 m sideways. '
        "<b style='color:#ed1c24'>Red</b>: holes, pixels where "
        f"{html.escape(reference)} has a surface but the model's accumulated alpha is below 0.5; dimmed: "
        f"no reference surface. Overall hole fraction {_format(metrics.get('hole_fraction_leaned'), 'pct')} "
        f"(unleaned test views: {_format(metrics.get('hole_fraction_test'), 'pct')}).</p>"
    ]
    by_view: dict[str, list] = {}
    for item in evaluation.leaned:
        by_view.setdefault(item.name, []).append(item)
    for name, items in by_view.items():
        figures = "".join(
            _figure(
                plots.png(plots.hole_overlay(i.render, i.holes, i.surface)),
                f"{name} {i.label}",
                f"{i.label} · holes {100 * i.hole_fraction:.2f} %",
            )
            for i in items
        )
        parts.append(f"<h3>{html.escape(name)}</h3><div class='row lean'>{figures}</div>")
    return "".join(parts)


def _geometry(evaluation: RunEvaluation) -> str:
    points, metrics = evaluation.points, evaluation.metrics
    if points is None:
        why = _reason(metrics, "chamfer_m") or "no ground truth"
        return f'<p class="note">Not computed: {html.escape(why)}.</p>'
    return (
        '<p class="note">Surface samples of the exported mesh within the training frusta, coloured by their '
        f"distance to the ground truth (green: within the {points.threshold_m:g} m threshold, counts for "
        "precision); violet: ground-truth samples farther than the threshold from the reconstruction "
        f"(missed, against recall). F-score {_format(metrics.get('fscore'), 'ratio')}, precision "
        f"{_format(metrics.get('precision'), 'ratio')}, recall {_format(metrics.get('recall'), 'ratio')}.</p>"
        + _figure(plots.point_cloud_figure(points), "point cloud coloured by distance", wide=True)
    )


def _training(run_dir: Path) -> str:
    curves = plots.training_curves(layout.read_metrics(run_dir))
    if curves is None:
        return f'<p class="note">No training metrics ({html.escape(str(layout.metrics_path(run_dir)))}).</p>'
    return _figure(curves, "training curves", wide=True)


def _physics(evaluation: RunEvaluation) -> str:
    metrics, drops = evaluation.metrics, evaluation.physics
    if drops is None:
        why = _reason(metrics, "fall_through_rate") or _reason(metrics, "physics") or "not run"
        return f'<p class="note">Not computed: {html.escape(why)}.</p>'
    background = evaluation.points.ground_truth if evaluation.points is not None else None
    summary = (
        f"{_format(metrics.get('physics_probes'), 'int')} probes (4 cm spheres) rest on the ground truth; "
        f"on <code>{html.escape(str(metrics.get('physics_mesh')))}</code> "
        f"{_format(metrics.get('fall_through_rate'), 'pct')} fell through and the others rest "
        f"{_format(metrics.get('height_error_mean_m'), 'm')} from their ground-truth height on average "
        f"(max {_format(metrics.get('height_error_max_m'), 'm')})."
    )
    return f'<p class="note">{summary}</p>' + _figure(
        plots.physics_figure(drops, background), "physics probes", wide=True
    )


def _config_value(value) -> str:
    return value if isinstance(value, str) else json.dumps(value)


def _configuration(run_dir: Path) -> str:
    parts = []
    config_path = layout.config_path(run_dir)
    config = yaml.safe_load(config_path.read_text()) if config_path.is_file() else None
    if isinstance(config, dict):
        items = "".join(
            f"<div><b>{html.escape(str(k))}</b>: {html.escape(_config_value(v))}</div>"
            for k, v in config.items()
        )
        parts.append(f"<h3>config.yaml</h3><div class='config'>{items}</div>")
    else:
        parts.append(f'<p class="note">No configuration ({html.escape(str(config_path))}).</p>')
    summary_path = layout.summary_path(run_dir)
    summary = json.loads(summary_path.read_text()) if summary_path.is_file() else {}
    skips = summary.get("skips") or []
    parts.append("<h3>Skipped work (summary.json)</h3>")
    if skips:
        parts.append(
            "<ul class='skips'>" + "".join(f"<li>{html.escape(str(s))}</li>" for s in skips) + "</ul>"
        )
    else:
        parts.append('<p class="note">None recorded.</p>')
    return "".join(parts)


def render_report(evaluation: RunEvaluation) -> str:
    """The report page as one HTML string."""
    metrics, run_dir = evaluation.metrics, evaluation.run_dir
    bodies = {
        "metrics": _metric_tables(metrics),
        "test-views": _test_views(evaluation),
        "leaned-views": _leaned_views(evaluation),
        "geometry": _geometry(evaluation),
        "training": _training(run_dir),
        "physics": _physics(evaluation),
        "configuration": _configuration(run_dir),
    }
    sections = "".join(
        f'<section id="{sid}"><h2>{SECTIONS[sid]}</h2>{bodies[sid]}</section>' for sid in SECTIONS
    )
    nav = "".join(f'<a href="#{sid}">{title}</a>' for sid, title in SECTIONS.items())
    gt = metrics.get("gt_dir") or "none (geometric and physics metrics need --gt)"
    sub = (
        f"method {metrics.get('method') or '?'} · scene {metrics.get('scene_dir')} · ground truth {gt} · "
        f"evaluated {_dt.datetime.now().strftime('%Y-%m-%d %H:%M')}"
    )
    title = f"lts eval — {run_dir.resolve().name}"
    return (
        '<!DOCTYPE html><html lang="en"><head><meta charset="utf-8">'
        '<meta name="viewport" content="width=device-width, initial-scale=1">'
        f"<title>{html.escape(title)}</title><style>{_CSS}</style></head><body>"
        f"<header><h1>Run report: {html.escape(str(run_dir))}</h1>"
        f"<div class='sub'>{html.escape(sub)}</div></header>"
        f"<nav>{nav}</nav><main>{sections}</main>"
        "<footer>lidar-ts · lts eval RUN_DIR · every image is embedded in this file</footer></body></html>\n"
    )


def write_report(evaluation: RunEvaluation, path: str | Path | None = None) -> Path:
    """Write the report (default ``RUN_DIR/report.html``) and return its path."""
    path = Path(path) if path is not None else evaluation.run_dir / REPORT_FILE
    path.write_text(render_report(evaluation), encoding="utf-8")
    return path
