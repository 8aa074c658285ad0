#!/usr/bin/env bash
# Builds the device firmware for a Cortex-M4F (firmware/, thumbv7em-none-eabihf) and prints
# its sections. One command, two toolchains:
#   - a rustup toolchain with the thumbv7em-none-eabihf target installed builds it as it is;
#   - otherwise (these machines: rustup has no thumb target and cannot fetch one) Debian's
#     rustc-web 1.96 builds `core` for the target from rust-web-src (-Zbuild-std=core, allowed on a
#     stable compiler by RUSTC_BOOTSTRAP=1) and links with lld-22 (Debian's rust-lld); this script
#     installs those packages (and qemu-system-arm, which runs the firmware) when it runs as root.
#
#   scripts/build-firmware.sh                 the release ELF, its path on the last line
#   scripts/build-firmware.sh --no-semihosting  the same without the debugger console (a real part)
#
# The ELF: firmware/target/thumbv7em-none-eabihf/release/smile-firmware. Boot it under QEMU:
#   qemu-system-arm -machine mps2-an386 -cpu cortex-m4 -display none -monitor none \
#     -serial pty -semihosting-config enable=on,target=native -kernel <ELF>
set -euo pipefail
cd "$(dirname "$0")/.."

TARGET=thumbv7em-none-eabihf
features=()
for arg in "$@"; do
  case "$arg" in
    --no-semihosting) features=(--no-default-features) ;;
    -h|--help) sed -n '2,17p' "$0"; exit 0 ;;
    *) echo "build-firmware.sh: unknown argument '$arg' (try --help)" >&2; exit 2 ;;
  esac
done

if command -v rustup >/dev/null && rustup target list --installed 2>/dev/null | grep -qx "$TARGET"; then
  echo "build-firmware.sh: rustup's $TARGET target" >&2
  (cd firmware && cargo build --release --target "$TARGET" "${features[@]}")
else
  need=()
  [ -x /usr/bin/rustc ] && /usr/bin/rustc --version 2>/dev/null | grep -q '^rustc 1\.\(9[6-9]\|[1-9][0-9][0-9]\)' || need+=(rustc-web cargo-web)
  [ -d /usr/lib/rustlib/src/rust/library/core ] || need+=(rust-web-src)
  command -v ld.lld-22 >/dev/null || need+=(lld-22)
  command -v qemu-system-arm >/dev/null || need+=(qemu-system-arm)
  if [ ${#need[@]} -gt 0 ]; then
    if [ "$(id -u)" != 0 ]; then
      echo "build-firmware.sh: no rustup $TARGET target, and Debian's ${need[*]} are missing;" \
        "install them (apt-get install ${need[*]}) or run this as root" >&2
      exit 1
    fi
    echo "build-firmware.sh: installing Debian's ${need[*]}" >&2
    apt-get update -q >/dev/null
    DEBIAN_FRONTEND=noninteractive apt-get install -y -q "${need[@]}" >/dev/null
  fi
  echo "build-firmware.sh: Debian's $(/usr/bin/rustc --version) with -Zbuild-std=core" >&2
  (cd firmware && RUSTC=/usr/bin/rustc RUSTC_BOOTSTRAP=1 /usr/bin/cargo build --release \
    --target "$TARGET" -Zbuild-std=core "${features[@]}")
fi

ELF=firmware/target/$TARGET/release/smile-firmware
# The sections a part's flash (vector table, code, read-only data, .data's initial values) and
# RAM (.data, .bss) hold; .blob_flash is the blob's flash region, reserved, not in the image.
readelf -S -W "$ELF" | sed 's/^ *\[ *[0-9]*\] *//' | while read -r name _type _addr _off size _rest; do
  case "$name" in
    .vector_table|.text|.rodata|.data|.bss|.uninit|.blob_flash) printf '  %-14s %8d B\n' "$name" "$((16#$size))" >&2 ;;
  esac
done
echo "$ELF"
