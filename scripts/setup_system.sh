#!/usr/bin/env bash
# Installs the Debian packages the tests need, only those missing (idempotent; no network
# when everything is there). Today: Mesa's EGL + software OpenGL, through which VTK renders
# offscreen without a display or GPU (the VTK-comparison tests in tests/python).
set -euo pipefail
packages=(libegl1 libegl-mesa0 libgl1-mesa-dri libgl1)
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
