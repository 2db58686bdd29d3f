#!/usr/bin/env bash
# What the test suite needs beyond Python packages: Debian's Chromium, which
# tests/test_report_browser.py drives headless to open the HTML report.  Installed
# with apt-get when missing (as root, or with sudo -n); nothing to do when a
# chromium is on PATH, SOFTRAS_CHROMIUM names one, or SOFTRAS_ALLOW_NO_BROWSER=1.
set -euo pipefail
if [ "${SOFTRAS_ALLOW_NO_BROWSER:-}" = 1 ] || [ -n "${SOFTRAS_CHROMIUM:-}" ] \
        || command -v chromium >/dev/null 2>&1; then
    exit 0
fi
if ! command -v apt-get >/dev/null 2>&1; then
    echo "install_test_tools: no chromium and no apt-get: install Chromium, or set SOFTRAS_ALLOW_NO_BROWSER=1" >&2
    exit 2
fi
as_root=()
[ "$(id -u)" = 0 ] || as_root=(sudo -n)
"${as_root[@]}" apt-get update -qq >/dev/null
DEBIAN_FRONTEND=noninteractive "${as_root[@]}" apt-get install -y -qq chromium >/dev/null
