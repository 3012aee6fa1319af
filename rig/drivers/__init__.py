"""Hardware drivers behind one interface (open / start / read / stop / close, health counters).

Protocol modules (``*_protocol``) are pure byte parsers; driver modules import their vendor
library (pyserial, depthai, pyusb, ouster-sdk) only when a device is opened.
"""

from rig.drivers.base import DeviceError, Driver, Health, Message, ParseError, now_ns

__all__ = ["DeviceError", "Driver", "Health", "Message", "ParseError", "now_ns"]
