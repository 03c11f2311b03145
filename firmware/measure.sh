#!/usr/bin/env bash
# Footprint and speed of the head firmware (benchmarks, not tests):
#   - flash (text+rodata) and static RAM (data+bss) of the release ELF, real-board build and
#     QEMU build (`arm-none-eabi-size -A`), and a check that no core::fmt float code is linked;
#   - instructions per 4-5-3 inference, counted in QEMU with `-icount shift=0` (1 instruction =
#     1 ns of virtual time; SysTick counts at 168 MHz), from the `bench` build's Bench request
#     (2000 inferences, minus an empty loop).
# Targets (issue 4): <= 24 KiB flash, <= 4 KiB static RAM, <= 900 instructions per inference.
# Usage: firmware/measure.sh [MODEL.bin]   (default: the seeded sample blob of the QEMU tests)
# Needs: qemu-system-arm, binutils-arm-none-eabi (apt-get install -y qemu-system-arm binutils-arm-none-eabi).
set -euo pipefail
cd "$(dirname "$0")/.."
for tool in qemu-system-arm arm-none-eabi-size arm-none-eabi-nm; do
  command -v "$tool" >/dev/null || { echo "error: $tool not found (apt-get install -y qemu-system-arm binutils-arm-none-eabi)" >&2; exit 1; }
done
target_dir=$(cargo metadata --format-version 1 --no-deps | sed -n 's/.*"target_directory":"\([^"]*\)".*/\1/p')
elf="$target_dir/thumbv7em-none-eabihf/firmware/hvs-firmware"
work=$(mktemp -d)
qemu_pid=
cleanup() { if [ -n "$qemu_pid" ]; then kill "$qemu_pid" 2>/dev/null; wait "$qemu_pid" 2>/dev/null; fi; rm -rf "$work"; }
trap cleanup EXIT

build() { cargo build --quiet --locked --profile firmware -p hvs-firmware --target thumbv7em-none-eabihf "$@"; }

# Flash: every allocated section with contents whose load address (LMA) lies in the code
# flash (0x08000000..+768 KiB): .vector_table, .text, .rodata, .data's initial values, veneers.
# The image end (highest LMA + size, alignment gaps included) must fit too. Static RAM: every
# allocated section whose address (VMA) lies in RAM (.data, .bss, .uninit); the stack is the
# rest of RAM and is measured on the head (`stack peak` in Info, see below).
FLASH_BUDGET=24576
RAM_BUDGET=16384
# sections ELF -> "flash BYTES END PARTS|ram BYTES PARTS" from `arm-none-eabi-objdump -h`.
sections() {
  arm-none-eabi-objdump -h "$1" | python3 -c '
import sys
lines = sys.stdin.read().splitlines()
flash = ram = end = 0
fparts, rparts = [], []
for i, l in enumerate(lines):
    f = l.split()
    if len(f) < 7 or not f[0].isdigit():
        continue
    name, size, vma, lma = f[1], int(f[2], 16), int(f[3], 16), int(f[4], 16)
    flags = lines[i + 1]
    if "ALLOC" not in flags:
        continue
    if "CONTENTS" in flags and 0x08000000 <= lma < 0x080C0000:
        flash += size
        end = max(end, lma + size - 0x08000000)
        if size:
            fparts.append(f"{name} {size}")
    if 0x20000000 <= vma < 0x20020000:
        ram += size
        if size:
            rparts.append(f"{name} {size}")
print(flash, end, " + ".join(fparts), "|", ram, " + ".join(rparts) or "none", sep="\t")'
}
footprint() { # name elf
  local flash end parts _ ram rparts
  IFS=$'\t' read -r flash end parts _ ram rparts < <(sections "$2")
  local verdict="flash within 24 KiB"
  if [ "$flash" -gt "$FLASH_BUDGET" ] || [ "$end" -gt "$FLASH_BUDGET" ]; then verdict="FLASH OVER 24 KiB"; flash_over=1; fi
  printf '%-30s flash %6d B (%s; image ends at +%d)   static RAM %5d B (%s)   %s\n' "$1" "$flash" "$parts" "$end" "$ram" "$rparts" "$verdict"
  if arm-none-eabi-nm -C "$2" | grep -Eq 'float_to_decimal|flt2dec|float_to_exponential|core::fmt::float'; then
    echo "  FAIL: core::fmt float formatting is linked into $1" >&2; exit 1
  fi
}
static_ram() { # elf -> bytes of every allocated section in RAM
  local _f _e _p _s ram _r
  IFS=$'\t' read -r _f _e _p _s ram _r < <(sections "$1")
  echo "$ram"
}
flash_over=

echo "== footprint (profile firmware: opt-level s, fat LTO, panic=abort)"
build;                 cp "$elf" "$work/board.elf"; footprint "board (HSE/PLL 168 MHz, MCDC)" "$work/board.elf"
build --features pwm;  cp "$elf" "$work/pwm.elf";   footprint "board, PWM servos" "$work/pwm.elf"
build --features bench,qemu; cp "$elf" "$work/bench.elf"
build --features qemu; cp "$elf" "$work/qemu.elf";  footprint "QEMU (HSI 16 MHz, MCDC)" "$work/qemu.elf"
echo "   no core::fmt float formatting linked (checked with arm-none-eabi-nm)"

model=${1:-}
if [ -z "$model" ]; then
  model="$work/sample.bin"
  cargo run --quiet --locked -p hvs-tests --example sample_blob -- "$model" 1
fi
cargo build --quiet --locked -p hvs-host
hvs="$target_dir/debug/hvs"

echo "== instructions per inference (QEMU netduinoplus2, -icount shift=0, model $model)"
port=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
timeout 120 qemu-system-arm -machine netduinoplus2 -display none -monitor none -nodefaults \
  -icount shift=0,sleep=off \
  -serial "tcp:127.0.0.1:$port,server=on,wait=on,nodelay=on" -serial null \
  -device "loader,file=$model,addr=0x080C0000,force-raw=on" \
  -kernel "$work/bench.elf" 2>/dev/null &
qemu_pid=$!
out=$(timeout 60 "$hvs" head --connect "tcp:127.0.0.1:$port" --timeout-ms 20000 bench --count 2000)
echo "   $out"
instr=$(sed -n 's/.*instructions_per_inference_icount0=\([0-9.]*\).*/\1/p' <<<"$out")
shape=$("$hvs" info "$model" | sed -n 's/^topology: *\([0-9-]*\).*/\1/p')
if [ "$shape" = "4-5-3" ]; then
  echo "   instructions per 4-5-3 inference: $instr (target <= 900)"
else
  echo "   instructions per ${shape:-?} inference: $instr (the 900 target is for 4-5-3)"
fi
