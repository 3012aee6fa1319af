"""USB enumeration with pyusb: OAK cameras and USB-serial adapters, mapped to their serial ports."""

from __future__ import annotations

from pathlib import Path
from typing import Any

#: (vendor id, product id or None for any) → what it is.
KNOWN_DEVICES: dict[tuple[int, int | None], str] = {
    (0x03E7, None): "Luxonis OAK (Movidius)",
    (0x10C4, 0xEA60): "Silicon Labs CP210x USB-serial (RPLIDAR, many 2D LiDARs)",
    (0x1A86, 0x7523): "QinHeng CH340 USB-serial (LDROBOT adapters)",
    (0x1A86, 0x55D4): "QinHeng CH9102 USB-serial",
    (0x0403, 0x6001): "FTDI FT232 USB-serial",
}


def _what(vid: int, pid: int) -> str | None:
    return KNOWN_DEVICES.get((vid, pid)) or KNOWN_DEVICES.get((vid, None))


def serial_ports_by_usb(sys_root: Path = Path("/sys")) -> dict[tuple[int, int], list[str]]:
    """``{(bus, address): ["/dev/ttyUSB0", ...]}`` read from sysfs (empty where there is none)."""
    out: dict[tuple[int, int], list[str]] = {}
    tty_root = sys_root / "class" / "tty"
    if not tty_root.is_dir():
        return out
    for tty in sorted(tty_root.iterdir()):
        try:
            dev = (tty / "device").resolve()
        except OSError:
            continue
        for parent in [dev, *dev.parents]:
            bus, addr = parent / "busnum", parent / "devnum"
            if bus.is_file() and addr.is_file():
                key = (int(bus.read_text()), int(addr.read_text()))
                out.setdefault(key, []).append(f"/dev/{tty.name}")
                break
    return out


def list_usb_devices() -> list[dict[str, Any]]:
    """USB devices of interest: ``[{"vid", "pid", "bus", "address", "what", "serial_ports"}]``.

    Empty when there are none, or when pyusb has no backend (libusb) or no permission.
    """
    try:
        import usb.core
    except ImportError:
        return []
    try:
        found = list(usb.core.find(find_all=True) or [])
    except (usb.core.NoBackendError, usb.core.USBError, ValueError):
        return []
    ports = serial_ports_by_usb()
    out = []
    for d in found:
        what = _what(d.idVendor, d.idProduct)
        if what is None:
            continue
        out.append(
            {
                "vid": f"{d.idVendor:04x}",
                "pid": f"{d.idProduct:04x}",
                "bus": d.bus,
                "address": d.address,
                "what": what,
                "serial_ports": ports.get((d.bus, d.address), []),
            }
        )
    return out


def reset_oak(bus: int | None = None, address: int | None = None) -> int:
    """USB-reset OAK devices (all, or the one at ``bus``/``address``); returns how many were reset."""
    import usb.core

    from rig.drivers.base import DeviceError

    try:
        found = list(usb.core.find(find_all=True, idVendor=0x03E7) or [])
    except (usb.core.NoBackendError, usb.core.USBError) as exc:
        raise DeviceError(f"cannot enumerate USB devices: {exc}") from exc
    count = 0
    for d in found:
        if bus is not None and (d.bus, d.address) != (bus, address):
            continue
        d.reset()
        count += 1
    return count
