#!/bin/sh
# System packages: libraries for off-screen 3D preview (`shapedisplay preview -o shot.png`)
# and, with options, the studio's and the C runtime's toolchains (below)
# on a headless Linux machine without a GPU.
#
# The VTK wheels used by pyvista load OpenGL at run time. Without an X display
# they render through EGL with Mesa's software rasterizer (llvmpipe), which
# needs exactly these Debian/Ubuntu packages:
#   libegl1         EGL loader (libglvnd)
#   libegl-mesa0    Mesa's EGL vendor library (surfaceless platform)
#   libgl1-mesa-dri Mesa's software rasterizer (swrast/llvmpipe DRI driver)
# Nothing else (no Xvfb, no OSMesa) is needed.
#
#   --with-xvfb   also install xvfb (provides xvfb-run), used only by the test
#                 of the interactive window (tests/test_viewer.py); off-screen
#                 pictures never need it.
#   --with-studio the studio's needs: clang, lld, wasi-libc and the wasm32
#                 compiler runtime (the C runtime built to WebAssembly for the
#                 page), and chromium (the headless browser of the studio's
#                 tests, driven by Playwright).
#   --with-toolchains
#                 also install the C runtime's cross toolchains, used by
#                 `make -C runtime-c wasm|m4` and their tests:
#                   clang lld wasi-libc libclang-rt-dev-wasm32   WebAssembly (wasm32-wasi)
#                   libclang-rt-dev                               clang's sanitizer and libFuzzer
#                                                                 runtimes (`make -C runtime-c fuzz`)
#                   gcc-arm-none-eabi libnewlib-arm-none-eabi     Cortex-M4F bare metal
#                   qemu-system-arm                               runs the M4F build (mps2-an386)
#
# Idempotent and non-interactive: does nothing when the packages are present,
# and only prints what to install when it is not root or apt-get is absent.
set -eu

PACKAGES="libegl1 libegl-mesa0 libgl1-mesa-dri"
for arg in "$@"; do
    case "$arg" in
        --with-xvfb) PACKAGES="$PACKAGES xvfb" ;;
        --with-studio) PACKAGES="$PACKAGES clang lld wasi-libc libclang-rt-dev-wasm32 chromium" ;;
        --with-toolchains) PACKAGES="$PACKAGES clang lld wasi-libc libclang-rt-dev-wasm32 libclang-rt-dev gcc-arm-none-eabi libnewlib-arm-none-eabi qemu-system-arm" ;;
        *) echo "install-system-deps: unknown option '$arg' (valid: --with-xvfb, --with-studio, --with-toolchains)" >&2; exit 2 ;;
    esac
done

missing=""
if command -v dpkg-query >/dev/null 2>&1; then
    for p in $PACKAGES; do
        if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
            missing="$missing $p"
        fi
    done
else
    echo "install-system-deps: no dpkg on this system; off-screen 3D preview needs EGL + Mesa (llvmpipe) or OSMesa from your package manager" >&2
    exit 0
fi

if [ -z "$missing" ]; then
    echo "install-system-deps: all present ($PACKAGES)"
    exit 0
fi

if [ "$(id -u)" != "0" ] || ! command -v apt-get >/dev/null 2>&1; then
    echo "install-system-deps: missing:$missing" >&2
    echo "install-system-deps: run as root: apt-get install -y --no-install-recommends$missing" >&2
    exit 0
fi

echo "install-system-deps: installing$missing"
export DEBIAN_FRONTEND=noninteractive
# several people may share this machine's apt: wait for the lock instead of failing
apt-get -o DPkg::Lock::Timeout=600 update -q
apt-get -o DPkg::Lock::Timeout=600 install -y -q --no-install-recommends $missing
