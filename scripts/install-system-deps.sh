#!/usr/bin/env bash
# System packages the tests need: a second C compiler (clang), valgrind,
# cppcheck, cmake, and for `make embedded` the bare-metal Arm toolchain
# (gcc-arm-none-eabi, libnewlib-arm-none-eabi) and QEMU's Arm system emulator
# (qemu-system-arm; about 60 s and 0.9 GB with --no-install-recommends).
# Idempotent: installs only what is missing. Called by `make test` and
# .ci/run; needs root (or sudo) and the Debian package registry.
set -euo pipefail
need=()
command -v clang >/dev/null 2>&1 || need+=(clang)
command -v valgrind >/dev/null 2>&1 || need+=(valgrind)
command -v cppcheck >/dev/null 2>&1 || need+=(cppcheck)
command -v cmake >/dev/null 2>&1 || need+=(cmake)
command -v arm-none-eabi-gcc >/dev/null 2>&1 || need+=(gcc-arm-none-eabi)
[ -f /usr/lib/arm-none-eabi/newlib/libc.a ] || need+=(libnewlib-arm-none-eabi)
command -v qemu-system-arm >/dev/null 2>&1 || need+=(qemu-system-arm)
[ ${#need[@]} -eq 0 ] && exit 0
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
echo "installing system packages: ${need[*]}" >&2
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null
