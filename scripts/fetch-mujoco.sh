#!/usr/bin/env bash
# Fetches MuJoCo 3.17.0's shared library from the official `mujoco` wheel on the Python package
# index into .mujoco/lib/ (ignored by git), so that `cargo build --release --features mujoco`
# links it with nothing set by hand (.cargo/config.toml points mujoco-rs there, and each crate's
# build script writes the same folder into the binaries' run-time search path).
#
#   scripts/fetch-mujoco.sh            the library only (what the Rust build needs)
#   scripts/fetch-mujoco.sh --python   also a virtual environment .mujoco/venv with the Python
#                                      `mujoco` and `gymnasium` packages, for the fidelity and
#                                      golden-trajectory scripts (docs/fidelity/, sim/tests/)
#
# Safe to run again: it skips what is already there and checks the wheel's SHA-256.
set -euo pipefail
cd "$(dirname "$0")/.."

VERSION=3.17.0
# The manylinux x86_64 wheel for CPython 3.11 (any CPython's wheel ships the same library).
WHEEL_SHA256=d66928d86a2d1b601bbaa4dc11db50214d17d5301bb8afd84721313b67ff0874
DEST=.mujoco
LIB=$DEST/lib

want_python=0
for arg in "$@"; do
  case "$arg" in
    --python) want_python=1 ;;
    -h|--help) sed -n '2,12p' "$0"; exit 0 ;;
    *) echo "fetch-mujoco.sh: unknown argument '$arg' (try --help)" >&2; exit 2 ;;
  esac
done

if [ "$(uname -s)-$(uname -m)" != "Linux-x86_64" ]; then
  echo "fetch-mujoco.sh: only Linux x86_64 is scripted; on $(uname -s)-$(uname -m) put MuJoCo $VERSION's" >&2
  echo "  libmujoco into a folder and set MUJOCO_DYNAMIC_LINK_DIR to it" >&2
  exit 1
fi
command -v python3 >/dev/null || { echo "fetch-mujoco.sh: python3 (with pip) is needed to download the wheel" >&2; exit 1; }

mkdir -p "$LIB"
if [ ! -f "$LIB/libmujoco.so.$VERSION" ]; then
  tmp=$(mktemp -d)
  trap 'rm -rf "$tmp"' EXIT
  echo "downloading the mujoco==$VERSION wheel (about 27 MB)"
  python3 -m pip download --quiet --no-deps --only-binary=:all: \
    --python-version 3.11 --platform manylinux_2_28_x86_64 --implementation cp \
    "mujoco==$VERSION" -d "$tmp"
  wheel=$(ls "$tmp"/mujoco-"$VERSION"-*.whl)
  got=$(sha256sum "$wheel" | cut -d' ' -f1)
  if [ "$got" != "$WHEEL_SHA256" ]; then
    echo "fetch-mujoco.sh: $wheel has SHA-256 $got, expected $WHEEL_SHA256" >&2
    exit 1
  fi
  python3 - "$wheel" "$LIB" "$VERSION" <<'PY'
import sys, zipfile, pathlib
wheel, lib, version = sys.argv[1], pathlib.Path(sys.argv[2]), sys.argv[3]
with zipfile.ZipFile(wheel) as z:
    name = f"mujoco/libmujoco.so.{version}"
    (lib / f"libmujoco.so.{version}.part").write_bytes(z.read(name))
    (lib / "LICENSE").write_bytes(z.read(f"mujoco-{version}.dist-info/licenses/LICENSE"))
(lib / f"libmujoco.so.{version}.part").rename(lib / f"libmujoco.so.{version}")
PY
fi
ln -sfn "libmujoco.so.$VERSION" "$LIB/libmujoco.so"
echo "MuJoCo $VERSION: $(cd "$LIB" && pwd)/libmujoco.so.$VERSION"

if [ "$want_python" = 1 ]; then
  if [ ! -x "$DEST/venv/bin/python" ]; then
    python3 -m venv "$DEST/venv"
  fi
  "$DEST/venv/bin/python" -m pip install --quiet "mujoco==$VERSION" "gymnasium==1.2.0" "numpy<3"
  echo "Python: $DEST/venv/bin/python ($("$DEST/venv/bin/python" -c 'import mujoco; print("mujoco", mujoco.__version__)'))"
fi
echo "next: cargo build --release --features mujoco"
