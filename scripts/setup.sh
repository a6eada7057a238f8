#!/usr/bin/env bash
# Create .venv and install everything the toolkit and its tests need, on a fresh Debian machine.
# Idempotent: re-running only installs what is missing.
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=${VENV:-.venv}
PYTHON=${PYTHON:-python3}

# Mitsuba's fast CPU variant (llvm_ad_rgb) needs libLLVM >= 16: Debian's libllvm19.
if ! ldconfig -p 2>/dev/null | grep -q 'libLLVM.so.19\|libLLVM-19'; then
  if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null; then
    echo "setup: installing libllvm19 (apt)"
    apt-get install -y -q libllvm19 >/dev/null 2>&1 || { apt-get update -q >/dev/null && apt-get install -y -q libllvm19 >/dev/null; }
  else
    echo "setup: warning: libllvm19 is missing and we are not root; Mitsuba will use the slow scalar_rgb variant (fix: sudo apt-get install libllvm19)" >&2
  fi
fi

# Headless Chromium: the test that opens orchestrate.capture's report.html in a real browser needs it.
if ! command -v chromium >/dev/null 2>&1; then
  if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null; then
    echo "setup: installing chromium (apt)"
    apt-get install -y -q chromium >/dev/null 2>&1 || { apt-get update -q >/dev/null && apt-get install -y -q chromium >/dev/null; }
  else
    echo "setup: warning: chromium is missing and we are not root; the browser test of report.html will skip (fix: sudo apt-get install chromium)" >&2
  fi
fi

if [ ! -x "$VENV/bin/python" ]; then
  echo "setup: creating $VENV"
  "$PYTHON" -m venv "$VENV"
fi
PIP="$VENV/bin/python -m pip"
# torch first, pinned to the release that lies on this machine's disk, so nothing pulls another one.
if ! "$VENV/bin/python" -c "import torch, torchvision" >/dev/null 2>&1; then
  echo "setup: installing torch 2.14.1 + torchvision 0.29.1"
  $PIP install -q "torch==2.14.1" "torchvision==0.29.1"
fi
stamp="$VENV/.unips-installed"
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ]; then
  echo "setup: installing the toolkit and its dependencies"
  $PIP install -q -e ".[test${EXTRAS:+,$EXTRAS}]" "torch==2.14.1" "torchvision==0.29.1"
  touch "$stamp"
fi
# Commands run inside the virtualenv: say how to enter it (the system Python lacks the packages).
echo "setup: $VENV is ready ($(du -sh "$VENV" 2>/dev/null | cut -f1) on disk); to run the commands yourself: source $VENV/bin/activate"
