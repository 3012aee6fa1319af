"""``rig``: the on-robot command line (list devices, record, check, inspect, replay, recover sessions)."""

from __future__ import annotations

import signal
import tempfile
import threading
from pathlib import Path
from typing import Any

import typer

from rig.cli_support import HELP_MARKUP, VERSION_OPTION, console, emit_json, output_file_option, run_app
from rig.errors import InputError
from rig.recording_options import (
    CAMERA_OPTION,
    DURATION_OPTION,
    RECORDING_ARGUMENT,
    START_OPTION,
    TOPICS_OPTION,
)

app = typer.Typer(
    rich_markup_mode=HELP_MARKUP,
    name="rig",
    help="On-robot tools: record time-stamped camera + LiDAR sessions and inspect them.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


@app.callback()
def _root(
    version: bool = VERSION_OPTION,
) -> None:
    """On-robot tools: record time-stamped camera + LiDAR sessions and inspect them."""


def _serial_ports() -> list[dict[str, Any]]:
    from serial.tools import list_ports

    return [
        {
            "port": p.device,
            "description": p.description,
            "vid": p.vid,
            "pid": p.pid,
            "serial": p.serial_number,
        }
        for p in list_ports.comports()
    ]


@app.command("list")
def list_devices(
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object."),
    reset_oak: bool = typer.Option(False, "--reset-oak", help="USB-reset every OAK first (a stuck device)."),
) -> None:
    """Devices found: USB devices of interest (with their serial ports), OAK cameras, serial ports."""
    from rig.drivers.oak import list_oak_devices
    from rig.drivers.usb import list_usb_devices

    reset = 0
    if reset_oak:
        from rig.drivers.base import DeviceError
        from rig.drivers.usb import reset_oak as usb_reset_oak

        try:
            reset = usb_reset_oak()
        except DeviceError as exc:
            console.print(f"[bold red]device error:[/] {exc}", highlight=False)
            raise SystemExit(1) from exc
        console.print(f"reset {reset} OAK device(s)")
    found = {"usb": list_usb_devices(), "oak": list_oak_devices(), "serial_ports": _serial_ports()}
    if reset_oak:
        found["oak_reset"] = reset
    if json_out:
        emit_json(found)
        return
    if not any(found.values()):
        console.print("no devices found")
    for d in found["usb"]:
        console.print(
            f"usb {d['vid']}:{d['pid']} bus {d['bus']} addr {d['address']}  {d['what']}  {d['serial_ports']}"
        )
    for d in found["oak"]:
        console.print(f"oak {d['id']}  {d['name']}  {d['state']}")
    for d in found["serial_ports"]:
        console.print(f"serial {d['port']}  {d['description']}")


def _status_table(s: dict[str, Any]) -> Any:
    from rich.table import Table

    table = Table(
        title=f"recording {s['out']}  {s['elapsed_s']:.1f} s  {s['bytes'] / 1e6:.1f} MB  queue {s['queue']}"
    )
    for col in ("topic", "messages", "Hz", "dropped"):
        table.add_column(col)
    for topic, n in sorted(s["written"].items()):
        table.add_row(topic, str(n), f"{s['rates_hz'].get(topic, 0):.1f}", str(s["dropped"].get(topic, 0)))
    for name, h in s["devices"].items():
        clock = h.get("clock") or {}
        offset = (
            f"offset {clock['offset_ns'] / 1e6:.3f} ms drift {clock['drift_ppm']:.1f} ppm" if clock else ""
        )
        table.add_row(
            f"[dim]{name}[/]",
            f"crc {h['crc_errors']} drop {h['dropped']}",
            f"reconn {h['reconnects']}",
            offset,
        )
    return table


def _record(
    recording: Any, duration: float | None, after_open: Any = None, sources_done: Any = None
) -> dict[str, Any]:
    from rich.live import Live

    stop = threading.Event()
    previous = {sig: signal.signal(sig, lambda *_: stop.set()) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        with Live(console=console, refresh_per_second=2, transient=not console.is_terminal) as live:
            return recording.run(
                duration,
                stop,
                on_tick=lambda s: live.update(_status_table(s)),
                after_open=after_open,
                sources_done=sources_done,
            )
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


@app.command()
def record(
    out: Path = output_file_option(..., "--out", help="Session file to write (.mcap)."),
    config: Path | None = typer.Option(None, "--config", help="rig.yaml describing the devices."),
    sim: Path | None = typer.Option(
        None, "--sim", help="Virtual-rig scene folder: record it through mock devices."
    ),
    duration: float | None = typer.Option(
        None, "--duration", help="Seconds to record (default: until Ctrl-C)."
    ),
    corrupt_rate: float = typer.Option(
        1e-4, "--corrupt-rate", min=0.0, max=1.0, help="--sim: fraction of serial bytes corrupted."
    ),
    unplug_at: float | None = typer.Option(
        None, "--unplug-at", min=0.0, help="--sim: unplug the serial LiDAR after S s."
    ),
    unplug_for: float = typer.Option(
        1.0, "--unplug-for", min=0.0, help="--sim: seconds the serial LiDAR stays unplugged."
    ),
    once: bool = typer.Option(
        False,
        "--once",
        help="--sim: play the scene once and stop when it ends (by default the mock devices loop it "
        "until --duration or Ctrl-C).",
    ),
    json_out: bool = typer.Option(False, "--json", help="Print the summary as one JSON object."),
) -> None:
    """Record a session from the devices of a rig.yaml, or from a simulated scene through mock devices.

    SIGINT/SIGTERM finish the file cleanly; a full disk stops recording with a valid file and exit
    status 1.
    """
    from rig.drivers.base import DeviceError
    from rig.record import Recording, silent_devices, written_line

    if (config is None) == (sim is None):
        raise InputError("give exactly one of --config RIG.yaml or --sim SCENE_DIR", field="--config/--sim")
    if duration is not None and not duration > 0:
        raise InputError(f"expected seconds > 0, got {duration}", field="--duration")
    if once and sim is None:
        raise InputError("plays a simulated scene once; give the scene with --sim SCENE_DIR", field="--once")
    try:
        if sim is not None:
            from rig.mock.sim_rig import build_sim_rig

            with tempfile.TemporaryDirectory(prefix="rig-sim-") as work:
                rig = build_sim_rig(sim, work, corrupt_rate, unplug_at, unplug_for, once=once)
                meta = {"sim": rig.ground_truth()}
                try:
                    summary = _record(
                        Recording(rig.sources, out, meta), duration, rig.start_devices, rig.finished
                    )
                finally:
                    rig.stop_devices()
                summary["sim"] = rig.ground_truth()
                summary["sim"]["shortfalls"] = rig.shortfalls(summary["written"], summary["duration_s"])
        else:
            from rig.record import build_sources
            from rig.record_config import load_config

            assert config is not None
            cfg = load_config(config)
            rec = cfg.recorder
            options = {
                k: v
                for k, v in {
                    "queue_size": rec.get("queue_size"),
                    "policy": rec.get("policy"),
                    "image_format": rec.get("image_format"),
                    "chunk_size": int(rec["chunk_mb"] * (1 << 20)) if "chunk_mb" in rec else None,
                    "min_free_bytes": int(rec["min_free_mb"] * (1 << 20)) if "min_free_mb" in rec else None,
                }.items()
                if v is not None
            }
            summary = _record(Recording(build_sources(cfg), out, {"rig_yaml": cfg.raw}, options), duration)
    except DeviceError as exc:
        console.print(f"[bold red]device error:[/] {exc}", highlight=False)
        raise SystemExit(1) from exc
    if summary.get("error"):
        console.print(f"[bold red]recording stopped:[/] {summary['error']}", highlight=False)
    for line in summary.get("sim", {}).get("shortfalls", []) + silent_devices(summary):
        console.print(f"warning: {line}", style="yellow", highlight=False, markup=False)
    if json_out:
        emit_json(summary)
    else:
        console.print(written_line(out, summary["written"]), highlight=False, markup=False)
    if summary.get("error"):
        raise SystemExit(1)  # the file is valid, but the recording stopped early


@app.command()
def check(
    config: Path = typer.Option(..., "--config", help="rig.yaml describing the devices."),
    messages: int = typer.Option(3, "--messages", help="Messages to read from each device."),
    timeout: float = typer.Option(5.0, "--timeout", help="Seconds to wait for them, per device."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """Open each device of a rig.yaml, read a few messages, and report its health."""
    import time

    from rig.drivers.base import DeviceError
    from rig.record import build_sources
    from rig.record_config import load_config

    report: dict[str, Any] = {}
    for source in build_sources(load_config(config)):
        d = source.driver
        entry: dict[str, Any] = {"kind": d.kind, "ok": False, "messages": 0}
        try:
            d.open()
            d.start()
            deadline = time.monotonic() + timeout
            while entry["messages"] < messages and time.monotonic() < deadline:
                entry["messages"] += len(d.read(0.1))
            entry.update(
                ok=entry["messages"] >= messages,
                device_id=d.device_id(),
                health=d.health.as_dict(),
                device=d.describe(),
            )
        except (DeviceError, OSError) as exc:
            entry["error"] = str(exc)
        finally:
            try:
                d.stop()
                d.close()
            except (DeviceError, OSError):
                pass
        report[d.name] = entry
    if json_out:
        emit_json({"devices": report, "ok": all(e["ok"] for e in report.values())})
    else:
        for name, e in report.items():
            status = "[green]ok[/]" if e["ok"] else f"[red]FAIL[/] {e.get('error', '')}"
            console.print(f"{name} ({e['kind']}): {status}  {e['messages']} messages", highlight=False)
    if not all(e["ok"] for e in report.values()):
        raise SystemExit(1)  # typer.Exit's code is lost in the non-standalone entry point


@app.command()
def info(
    session: list[Path] = RECORDING_ARGUMENT,
    topics: str = TOPICS_OPTION,
    camera: int | None = CAMERA_OPTION,
    start: float = START_OPTION,
    duration: float | None = DURATION_OPTION,
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """Topics, counts, time span, recording errors, whether the file was cut short, where a bag's
    times come from, and which topic plays which role (as the offline commands pick them)."""
    from rig.recording_options import time_span
    from rig.session import parse_topic_map
    from rig.session.info import session_info

    result = session_info(session, time_span(start, duration), parse_topic_map(topics), camera)
    if json_out:
        emit_json(result)
        return
    for name, t in result["topics"].items():
        stamps = f"  {t['stamps']}" if "stamps" in t else ""
        console.print(f"{name:32s} {t['type']:32s} {t['count']:7d}{stamps}", highlight=False)
    console.print(f"{result['format']}: duration {result['duration_s']:.2f} s, {result['messages']} messages")
    if result["roles"] is not None:
        roles = ", ".join(f"{role}={topic}" for role, topic in result["roles"].items() if topic)
        console.print(f"roles: {roles}", highlight=False)
    else:
        console.print(f"roles: {result['roles_problem']}", highlight=False)
    if result["truncated"]:
        console.print(
            f"[yellow]truncated[/]: read up to the last complete chunk ({result['truncation_reason']}); "
            f"`rig recover {session[0]} --out FIXED.mcap` rewrites it as a valid file",
            highlight=False,
        )


@app.command()
def replay(
    session: Path = typer.Argument(..., help="Session file (.mcap)."),
    rate: float = typer.Option(
        1.0, "--rate", min=0.0, help="Speed factor (2 = twice as fast, 0 = as fast as possible)."
    ),
    topic: list[str] | None = typer.Option(None, "--topic", help="Only these topics (repeatable)."),
    json_out: bool = typer.Option(False, "--json", help="Print the summary as one JSON object."),
) -> None:
    """Re-emit a session's messages with their original timing (one line per message on stderr)."""
    from rig.session.replay import replay as run_replay

    def show(m: Any) -> None:
        if not json_out:
            console.print(f"{m.t_host} {m.topic} {m.msgtype}", highlight=False)

    stop = threading.Event()
    previous = signal.signal(signal.SIGINT, lambda *_: stop.set())
    try:
        result = run_replay(session, show, rate=rate, topics=topic or None, stop=stop)
    finally:
        signal.signal(signal.SIGINT, previous)
    if json_out:
        emit_json(result)


@app.command()
def recover(
    session: Path = typer.Argument(..., help="A (truncated) session file."),
    out: Path = output_file_option(..., "--out", help="The valid file to write."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """Salvage every complete record of a truncated recording into a valid MCAP file."""
    from rig.session.recover import recover as run_recover

    result = run_recover(session, out)
    if json_out:
        emit_json(result)
    else:
        state = f"truncated ({result['reason']})" if result["truncated"] else "complete"
        console.print(f"{session} was {state}: wrote {result['messages']} messages to {out}", highlight=False)


main = run_app(app, "rig")
