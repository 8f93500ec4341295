#!/usr/bin/env bash
# Builds the Debian root that tools/real_blender.py runs a real Blender window from:
# Debian unstable's Blender (5.2 LTS, Python 3.14), Mesa's software OpenGL, Xvfb and
# ImageMagick. Needs root, debootstrap (installed if missing) and Debian's package
# registry; about 1.5 GB and a few minutes. Idempotent.
# Usage: tools/real_blender_setup.sh [ROOT]   (default $REAL_BLENDER_ROOT or /var/tmp/real-blender/sid)
set -euo pipefail
ROOT=${1:-${REAL_BLENDER_ROOT:-/var/tmp/real-blender/sid}}
MIRROR=http://deb.debian.org/debian
# Unstable's Release file can be older than its validity window.
APT="apt-get -o Acquire::Check-Valid-Until=false -y -qq --no-install-recommends"
command -v debootstrap >/dev/null || { apt-get update -qq && apt-get install -y -qq debootstrap; }
if [ ! -x "$ROOT/usr/bin/apt-get" ]; then
  mkdir -p "$ROOT"
  debootstrap --variant=minbase --include=ca-certificates sid "$ROOT" "$MIRROR"
fi
# /proc and /dev are bound into the root only while this script runs.
MOUNTED=""
for d in proc dev; do
  mountpoint -q "$ROOT/$d" || { mount --bind "/$d" "$ROOT/$d" && MOUNTED="$MOUNTED $ROOT/$d"; }
done
trap 'for m in $MOUNTED; do umount "$m" 2>/dev/null || umount -l "$m"; done' EXIT
cp /etc/resolv.conf "$ROOT/etc/resolv.conf"
PKGS="blender python3-numpy xvfb xauth imagemagick libgl1-mesa-dri libegl-mesa0 python3-pip python3-attr
      python3-requests python3-typing-extensions"
if ! chroot "$ROOT" dpkg -s $PKGS >/dev/null 2>&1; then
  chroot "$ROOT" bash -c "apt-get -o Acquire::Check-Valid-Until=false update -qq && \
    DEBIAN_FRONTEND=noninteractive $APT install $(echo $PKGS)"
fi
# Blender's extensions add-on imports cattrs, which Debian does not package.
if ! chroot "$ROOT" python3 -c "import cattrs" 2>/dev/null; then
  mkdir -p "$ROOT/tmp/wheels"
  python3 -m pip download -q --no-deps -d "$ROOT/tmp/wheels" cattrs
  chroot "$ROOT" bash -c "python3 -m pip install -q --break-system-packages --no-deps --no-index /tmp/wheels/cattrs-*.whl"
fi
chroot "$ROOT" bash -c "HOME=/root blender --version" | head -1
