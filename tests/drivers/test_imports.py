"""Drivers and mocks import without their vendor libraries; listing works with no devices."""

import subprocess
import sys


def test_driver_and_mock_packages_load_no_vendor_library() -> None:
    code = (
        "import sys, rig.drivers, rig.mock, rig.session, rig.record, rig.cli;"
        "heavy = [m for m in ('depthai', 'usb', 'serial', 'ouster') if m in sys.modules];"
        "print(heavy); sys.exit(1 if heavy else 0)"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stdout + result.stderr


def test_usb_listing_is_empty_without_devices(tmp_path) -> None:
    from rig.drivers.usb import list_usb_devices, serial_ports_by_usb

    assert list_usb_devices() == []
    assert serial_ports_by_usb(tmp_path) == {}  # no sysfs tty tree
