"""Reading others' recordings with a topic map: ROS 1 bags, bare MCAP (rosbag2) files, timed by
header stamps."""

from pathlib import Path

import numpy as np
import pytest

from rig import InputError
from rig.session.foreign import list_topics, read_foreign, read_foreign_trajectory


def test_ros1_bag_pose_topics(real_data: Path) -> None:
    bag = real_data / "trajectories_evo" / "ROS_example.bag"
    topics = list_topics(bag)
    assert topics["groundtruth"] == ("geometry_msgs/msg/PoseStamped", 12765)
    traj = read_foreign_trajectory(bag, "groundtruth")
    assert len(traj.t_ns) == 12765 and np.all(np.diff(traj.t_ns) >= 0)
    assert traj.t_ns[0] == 1502792570283404827  # header stamp of the first message, ns
    np.testing.assert_allclose(np.linalg.norm(traj.quaternions, axis=1), 1.0, atol=1e-6)
    assert topics["ORB-SLAM"] == ("geometry_msgs/msg/PoseStamped", 8362)


def test_ros2_mcap_odometry_and_pose_with_covariance(real_data: Path) -> None:
    bag = real_data / "trajectories_evo" / "nav2_turtlebot.mcap"
    odom = read_foreign_trajectory(bag, "/odom")
    amcl = read_foreign_trajectory(bag, "/amcl_pose")
    assert len(odom.t_ns) == 2639 and len(amcl.t_ns) == 135
    assert np.all(odom.translations[:, 2] == 0)  # a ground robot
    first = next(read_foreign(bag, {"pose": "/amcl_pose"}))
    assert first.role == "pose" and first.value.shape == (4, 4) and first.t_host == amcl.t_ns[0]


def test_topic_map_errors_name_the_problem(real_data: Path) -> None:
    bag = real_data / "trajectories_evo" / "ROS_example.bag"
    with pytest.raises(InputError, match="not in the bag"):
        next(read_foreign(bag, {"image": "/realsense/color/image_raw/compressed"}))
    with pytest.raises(InputError, match="unknown role"):
        next(read_foreign(bag, {"lidar": "groundtruth"}))
    with pytest.raises(InputError, match="cannot be read as a pose"):
        next(read_foreign(real_data / "ouster" / "512x10_raw.bag", {"pose": "/os_node0/metadata"}))


def test_recorded_session_read_through_the_topic_map(tmp_path: Path) -> None:
    from tests.rig.test_session import write_session

    path = tmp_path / "s.mcap"
    write_session(path, frames=3, scans=2)
    got = list(read_foreign(path, {"image": "/camera/image/compressed", "points": "/lidar/points"}))
    assert [m.role for m in got].count("image") == 3 and [m.role for m in got].count("points") == 2
    scan = next(m.value for m in got if m.role == "points")
    assert scan.points.shape == (500, 3)
