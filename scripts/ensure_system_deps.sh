#!/usr/bin/env bash
# open3d loads libusb-1.0 when imported; make sure the system library is there.
# Installs it with apt when running as root, else says what to install and fails.
set -euo pipefail

if ldconfig -p 2>/dev/null | grep -q 'libusb-1\.0\.so\.0'; then
    exit 0
fi
if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then
    echo "installing the system library libusb-1.0-0 (open3d needs it) ..." >&2
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y -qq libusb-1.0-0 >/dev/null
    exit 0
fi
echo "error: the system library libusb-1.0 is missing (open3d needs it)." >&2
echo "       install the package libusb-1.0-0, e.g.: sudo apt-get install libusb-1.0-0" >&2
exit 1
