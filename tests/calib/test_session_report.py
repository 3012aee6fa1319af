"""The lines `lts calibrate SESSION` prints from its report."""

from __future__ import annotations

import math

from calib.session_calib import report_lines


def test_each_step_says_its_95_percent_interval_where_it_has_one() -> None:
    report = {
        "time": {"verdict": "ok", "reasons": [], "applied": True, "interval_95_s": 0.00313},
        "extrinsic": {
            "verdict": "ok",
            "reasons": [],
            "applied": True,
            "rotation_interval_95_deg": 0.653,
            "translation_interval_95_m": 0.0627,
        },
        "extrinsic_init": "--init",
    }
    assert report_lines(report) == [
        "time: ok ±3.1 ms (95 %)",
        "extrinsic: ok ±0.65° ±6.3 cm (95 %)",
        "rough extrinsic: --init",
    ]
    # A straight drive keeps two axes from the guess (no interval); a step that did not run has none.
    report["extrinsic"].update(verdict="poorly constrained", reasons=["why"], applied=False)
    report["extrinsic"]["rotation_interval_95_deg"] = math.inf
    report["time"] = {"verdict": "not run", "reasons": ["no motion"], "applied": False}
    assert report_lines(report)[:2] == [
        "time: not run (no motion) — not applied, the value from --init is kept",
        "extrinsic: poorly constrained (why) — not applied, the value from --init is kept",
    ]


def test_the_offset_searched_with_the_extrinsic_follows_the_motions() -> None:
    """The motion's offset refused, the one the extrinsic's search found applied with it."""
    searched = {"time_offset_s": 0.0141, "interval_95_s": 0.0032, "at_reach": False, "applied": True}
    report = {
        "time": {
            "verdict": "poorly constrained",
            "reasons": ["varies"],
            "applied": False,
            "with_the_extrinsic": searched,
        },
        "extrinsic": {"verdict": "ok", "reasons": [], "applied": True},
    }
    assert report_lines(report)[:2] == [
        "time: poorly constrained (varies) — not applied, the offset searched with the extrinsic is used",
        "time offset searched with the extrinsic: 14.1 ms ±3.2 ms (95 %) — applied",
    ]
    searched.update(applied=False, at_reach=True)
    assert report_lines(report)[:2] == [
        "time: poorly constrained (varies) — not applied, 0 s is kept",
        "time offset searched with the extrinsic: 14.1 ms ±3.2 ms (95 %) — not applied (at the edge of the "
        "window searched: it may lie past it)",
    ]
