#!/usr/bin/env bash
# Installs the Debian packages the tests and the C++/ParaView build need, only those missing
# (idempotent; no network when everything is there):
#  - Mesa's EGL + software OpenGL: pip's VTK renders offscreen through it (tests/python);
#  - Mesa's lavapipe (software Vulkan): the GPU ray caster's tests run on it without a GPU;
#  - ParaView 5.11 with its development files and Python (its VTK 9.2 builds the VTK mapper
#    and the plugin), cmake, Xvfb (Debian's VTK/ParaView windows need an X display), and the
#    -dev packages ParaView's CMake config looks for;
#  - ffmpeg: `fluidcast render -o run.mp4` encodes through it (and the tests count its frames
#    with ffprobe).
set -euo pipefail
packages=(
  libegl1 libegl-mesa0 libgl1-mesa-dri libgl1 mesa-vulkan-drivers libvulkan1
  paraview paraview-dev python3-paraview cmake xvfb xauth openmpi-bin
  libglew-dev libopenmpi-dev libexpat1-dev libdouble-conversion-dev liblz4-dev libutfcpp-dev
  libtiff-dev libfreetype-dev libgl2ps-dev libjpeg-dev liblzma-dev libxml2-dev libpng-dev
  libtheora-dev zlib1g-dev libeigen3-dev ffmpeg
)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]} == 0)); then
  exit 0
fi
sudo=""
if [[ $(id -u) -ne 0 ]]; then
  command -v sudo >/dev/null || { echo "need root (or sudo) to install: ${missing[*]}" >&2; exit 1; }
  sudo="sudo"
fi
echo "installing system packages: ${missing[*]}"
$sudo apt-get update -qq
DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
