"""Hardware drivers behind one interface (open / start / read / stop / close, health counters).

Protocol modules (``*_protocol``) are pure byte parsers with their own :class:`ParseError`;
driver modules import their vendor library (pyserial, depthai, pyusb, ouster-sdk) only when a
device is opened or listed.
"""

from rig.drivers.base import DeviceClockDriver, DeviceError, Driver, Health, Message, ParseError, now_ns
from rig.drivers.ld06 import Ld06Driver
from rig.drivers.livox import LivoxDriver
from rig.drivers.oak import OakDriver, OakPacket, list_oak_devices
from rig.drivers.ouster import OusterDriver, read_pcap
from rig.drivers.rplidar import RplidarDriver
from rig.drivers.usb import list_usb_devices, reset_oak

__all__ = [
    "DeviceClockDriver",
    "DeviceError",
    "Driver",
    "Health",
    "Ld06Driver",
    "LivoxDriver",
    "Message",
    "OakDriver",
    "OakPacket",
    "OusterDriver",
    "ParseError",
    "RplidarDriver",
    "list_oak_devices",
    "list_usb_devices",
    "now_ns",
    "read_pcap",
    "reset_oak",
]
