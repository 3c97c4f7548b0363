#!/usr/bin/env bash
# System libraries artic needs beyond PyPI: libusb-1.0-0 (loaded by open3d) and
# liburdfdom-tools (check_urdf, used by the URDF tests). Installs them with apt-get
# when missing; does nothing when they are present.
set -euo pipefail
need=()
for pkg in libusb-1.0-0 liburdfdom-tools; do
  dpkg -s "$pkg" >/dev/null 2>&1 || need+=("$pkg")
done
[ ${#need[@]} -eq 0 ] && exit 0
if ! command -v apt-get >/dev/null 2>&1; then
  echo "artic setup: please install ${need[*]} with your system's package manager" >&2
  exit 1
fi
sudo=""
[ "$(id -u)" -eq 0 ] || sudo="sudo"
echo "artic setup: installing ${need[*]}" >&2
$sudo apt-get update -qq
DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${need[@]}" >/dev/null
