"""The installed version of the toolkit."""

from importlib.metadata import PackageNotFoundError, version


def package_version() -> str:
    """The installed version of the ``lidar-ts`` distribution."""
    try:
        return version("lidar-ts")
    except PackageNotFoundError:
        return "unknown (not installed)"
