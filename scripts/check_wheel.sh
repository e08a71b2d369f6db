#!/usr/bin/env bash
# Installs a qogi wheel into a fresh virtual environment (no editable install,
# no -dev packages needed), and from a folder outside the checkout, with an
# empty HOME and no qogi environment variables, runs the short demo and the
# check that qogi's OpenCV and opencv-python-headless live together in one process.
#   scripts/check_wheel.sh dist/qogi-*.whl
set -euo pipefail
wheel=$(readlink -f "$1")
here=$(cd "$(dirname "$0")" && pwd)
PYTHON=${PYTHON:-python3}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
echo "check_wheel: $(basename "$wheel"), $(du -h "$wheel" | cut -f1)"
"$PYTHON" -m venv "$tmp/venv"
"$tmp/venv/bin/python" -m pip install -q --upgrade pip
"$tmp/venv/bin/python" -m pip install -q "$wheel"
cp "$here/opencv_coexistence.py" "$tmp/"
mkdir -p "$tmp/home" "$tmp/run"
cd "$tmp/run"
run() { env -i PATH="$tmp/venv/bin:/usr/bin:/bin" HOME="$tmp/home" "$@"; }
run python -c "import qogi, sys; print('check_wheel: qogi', qogi.__version__, 'from', qogi.__file__); assert '$PWD' not in qogi.__file__"
run python "$tmp/opencv_coexistence.py" qogi-first
run python "$tmp/opencv_coexistence.py" cv2-first
run qogi hitran list CH4 | head -3
run qogi demo --quick -q -o "$tmp/run/demo"
test -s "$tmp/run/demo/result.json"
echo "check_wheel: OK (fresh venv, wheel only, run from $tmp/run)"
