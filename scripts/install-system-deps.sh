#!/usr/bin/env bash
# Installs the EGL/Mesa libraries MuJoCo's headless renderer needs, when missing.
# Debian/Ubuntu, as root. Idempotent: does nothing when the libraries are present.
set -euo pipefail
need=()
# The linker cache is read once into a variable: `ldconfig -p | grep -q` under pipefail
# fails when grep exits early and ldconfig dies of SIGPIPE (a large cache), which made a
# present library look missing.
cache="$(ldconfig -p 2>/dev/null || true)"
have_lib() { grep -qF -- "$1" <<<"$cache"; }
have_lib 'libEGL.so.1 ' || need+=(libegl1)
have_lib 'libEGL_mesa.so.0 ' || need+=(libegl-mesa0)
have_lib 'libGL.so.1 ' || need+=(libgl1)
have_lib 'libOpenGL.so.0 ' || need+=(libopengl0)
ls /usr/lib/*/dri/swrast_dri.so /usr/lib/*/dri/*_dri.so >/dev/null 2>&1 || need+=(libgl1-mesa-dri)
if [ ${#need[@]} -eq 0 ]; then
  exit 0
fi
if [ "$(id -u)" -ne 0 ] || ! command -v apt-get >/dev/null 2>&1; then
  echo "twolink: headless rendering needs the Debian packages: ${need[*]} (run as root: apt-get install ${need[*]})" >&2
  exit 0
fi
echo "Installing EGL/Mesa libraries: ${need[*]}" >&2
export DEBIAN_FRONTEND=noninteractive
apt-get update -qq >/dev/null
apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null
