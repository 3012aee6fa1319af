#!/usr/bin/env bash
# Tools only the tests use: Debian's headless chromium screenshots report.html (tests/eval/test_report.py).
# Installed with apt when running as root; otherwise the screenshot test is skipped and this says why.
set -uo pipefail

if command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1; then
    exit 0
fi
if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then
    echo "installing chromium (headless screenshots of report.html in the tests) ..." >&2
    export DEBIAN_FRONTEND=noninteractive
    if apt-get update -qq && apt-get install -y -qq --no-install-recommends chromium >/dev/null; then
        exit 0
    fi
    echo "note: could not install chromium; the report screenshot test will be skipped" >&2
    exit 0
fi
echo "note: chromium is not installed (apt-get install chromium); the report screenshot test will be skipped" >&2
