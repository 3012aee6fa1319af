"""The real OAK path (depthai 3.x) on a machine without an OAK: a clear error, an empty list."""

import pytest

pytest.importorskip("depthai")

from rig.drivers import DeviceError, OakDriver, list_oak_devices


@pytest.mark.slow  # depthai searches for the device for ~10 s before it gives up
def test_missing_oak_is_a_device_error_and_listing_is_empty(capfd: pytest.CaptureFixture[str]) -> None:
    assert list_oak_devices() == []
    driver = OakDriver.from_device("cam", device_id="18443010C1E4F01200")
    with pytest.raises(DeviceError, match="18443010C1E4F01200"):
        driver.open()
    assert capfd.readouterr().out == ""  # depthai's log lines go to stderr, never stdout
