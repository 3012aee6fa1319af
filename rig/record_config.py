"""``rig.yaml``: which devices to record, on which topics, and how the recorder behaves.

```yaml
devices:
  - {name: cam, kind: oak, device_id: 18443010C1E4F01200, fps: 30, size: [640, 400], imu_hz: 200}
  - {name: lidar, kind: livox, host: 0.0.0.0, point_port: 56301, imu_port: 56401, scan_period_s: 0.1}
  - {name: scan2d, kind: ld06, port: /dev/ttyUSB0, model: ld19}
  - {name: rp, kind: rplidar, port: /dev/ttyUSB1, model: c1}
  - {name: os, kind: ouster, pcap: rec.pcap, meta: rec.json, topics: {points: /ouster/points}}
    # ouster: or hostname: os-1.local; topics: optional, per role
clock: {window_s: 60, min_pairs: 10}
recorder: {queue_size: 512, policy: drop-newest, image_format: jpeg, chunk_mb: 1, min_free_mb: 64}
```
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rig.clock import CLOCK_OPTIONS
from rig.data_file import load_data_file
from rig.errors import InputError
from rig.session.recorder import DROP_POLICIES

KINDS = ("oak", "livox", "ld06", "rplidar", "ouster")
_DEVICE_KEYS = {
    "oak": {"device_id", "fps", "size", "imu_hz"},
    "livox": {"host", "point_port", "imu_port", "scan_period_s", "split"},
    "ld06": {"port", "model", "baud"},
    "rplidar": {"port", "model", "baud"},
    "ouster": {"pcap", "meta", "hostname"},
}
_REQUIRED = {"ld06": {"port"}, "rplidar": {"port"}, "ouster": set()}
ROLES = ("image", "camera_info", "points", "imu")
RECORDER_OPTIONS = ("queue_size", "policy", "image_format", "chunk_mb", "min_free_mb")
IMAGE_FORMATS = ("jpeg", "png", "raw")


@dataclass
class DeviceConfig:
    name: str
    kind: str
    options: dict[str, Any]
    topics: dict[str, str]


@dataclass
class RigConfig:
    devices: list[DeviceConfig]
    clock: dict[str, Any] = field(default_factory=dict)
    recorder: dict[str, Any] = field(default_factory=dict)
    raw: dict[str, Any] = field(default_factory=dict)


def default_topics(name: str, kind: str) -> dict[str, str]:
    """Topics of a device unless ``rig.yaml`` says otherwise."""
    if kind == "oak":
        return {
            "image": f"/{name}/image/compressed",
            "camera_info": f"/{name}/camera_info",
            "imu": f"/{name}/imu",
        }
    if kind == "livox":
        return {"points": f"/{name}/points", "imu": f"/{name}/imu"}
    return {"points": f"/{name}/points"}


def parse_config(data: Any, source: str = "rig.yaml") -> RigConfig:
    """Validate a loaded ``rig.yaml``; every error names the field."""
    if not isinstance(data, dict) or not isinstance(data.get("devices"), list) or not data["devices"]:
        raise InputError("expected a mapping with a non-empty `devices` list", path=source, field="devices")
    devices, names = [], set()
    for i, d in enumerate(data["devices"]):
        where = f"devices[{i}]"
        if not isinstance(d, dict):
            raise InputError("expected a mapping", path=source, field=where)
        kind, name = d.get("kind"), d.get("name")
        if kind not in KINDS:
            raise InputError(f"kind {kind!r} is not one of {KINDS}", path=source, field=f"{where}.kind")
        if not isinstance(name, str) or not name or name in names:
            raise InputError("needs a unique non-empty name", path=source, field=f"{where}.name")
        names.add(name)
        options = {k: v for k, v in d.items() if k not in ("kind", "name", "topics")}
        unknown = set(options) - _DEVICE_KEYS[kind]
        if unknown:
            raise InputError(
                f"unknown option(s) {sorted(unknown)} for {kind}; "
                f"expected some of {sorted(_DEVICE_KEYS[kind])}",
                path=source,
                field=where,
            )
        missing = _REQUIRED.get(kind, set()) - set(options)
        if missing:
            raise InputError(f"missing {sorted(missing)}", path=source, field=where)
        if kind == "ouster" and not (("pcap" in options and "meta" in options) or "hostname" in options):
            raise InputError("ouster needs `pcap` and `meta`, or `hostname`", path=source, field=where)
        topics = {**default_topics(name, kind), **(d.get("topics") or {})}
        bad_roles = set(topics) - set(ROLES)
        if bad_roles:
            raise InputError(
                f"unknown topic role(s) {sorted(bad_roles)}", path=source, field=f"{where}.topics"
            )
        devices.append(DeviceConfig(name, kind, options, topics))
    for key in ("clock", "recorder"):
        if not isinstance(data.get(key, {}), dict):
            raise InputError("expected a mapping", path=source, field=key)
    for key, allowed in (("clock", CLOCK_OPTIONS), ("recorder", RECORDER_OPTIONS)):
        unknown = sorted(set(data.get(key, {})) - set(allowed))
        if unknown:
            raise InputError(
                f"unknown option(s) {unknown}; expected some of {list(allowed)}", path=source, field=key
            )
    for key, value in {**data.get("clock", {}), **data.get("recorder", {})}.items():
        section = "clock" if key in CLOCK_OPTIONS else "recorder"
        if key in ("policy", "image_format"):
            allowed = DROP_POLICIES if key == "policy" else IMAGE_FORMATS
            if value not in allowed:
                raise InputError(f"{value!r} is not one of {allowed}", path=source, field=f"recorder.{key}")
        elif isinstance(value, bool) or not isinstance(value, int | float) or value <= 0:
            raise InputError(
                f"expected a positive number, got {value!r}", path=source, field=f"{section}.{key}"
            )
    return RigConfig(devices, dict(data.get("clock", {})), dict(data.get("recorder", {})), data)


def load_config(path: str | Path) -> RigConfig:
    path = Path(path)
    if not path.is_file():
        raise InputError("no such rig config", path=path)
    return parse_config(load_data_file(path, "YAML", "rig config"), str(path))
