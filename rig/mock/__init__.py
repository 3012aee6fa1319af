"""Mock devices that speak the real wire protocols, fed by a virtual-rig scene.

Used by the tests and by ``rig record --sim``: a fake serial LiDAR on a pseudo-terminal (LD06 or
RPLIDAR bytes, corrupted bytes, unplug), a fake Livox Mid-360 on 127.0.0.1, and a fake OAK
(frames stamped by a drifting device clock).
"""

from rig.mock.device_clock import DriftingClock
from rig.mock.device_process import DeviceProcess
from rig.mock.fake_oak import FakeOakSource
from rig.mock.livox_sender import FakeLivox
from rig.mock.scene import Scene, latest_slice, slice_2d
from rig.mock.serial_lidar import FakeSerialLidar
from rig.mock.sim_rig import SimRig, build_sim_rig

__all__ = [
    "DeviceProcess",
    "DriftingClock",
    "FakeLivox",
    "FakeOakSource",
    "FakeSerialLidar",
    "Scene",
    "SimRig",
    "build_sim_rig",
    "latest_slice",
    "slice_2d",
]
