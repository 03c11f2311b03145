#!/usr/bin/env bash
# Footprint, stack and speed of the head firmware (benchmarks, not tests):
#   - flash of every board build: every allocated section stored in flash (vector table, text,
#     rodata, .data's initial values), from `arm-none-eabi-objdump -h`; static RAM (.data, .bss,
#     .uninit); and a check that no core::fmt float code is linked;
#   - the stack peak the head itself reports (`stack peak` in Info: the stack is painted at
#     reset) after a workload in QEMU: boot with two valid slots (A: 4-5-3, B: a posture-aware
#     9-16-3 that runs), 300 estimates, a Look sequence;
#   - instructions per inference, counted in QEMU with `-icount shift=0` (1 instruction = 1 ns of
#     virtual time; SysTick counts at 168 MHz), from the `bench` build's Bench request (2000
#     inferences, minus an empty loop): the default family's 4-5-3 net (inverse-depth-skip),
#     the thesis family's 4-5-3 net, and a 9-16-3 posture-aware net in the thesis family
#     (`--arch thesis`) and in the default family with its points in the cyclopean frame
#     (what `hvs train` writes for a posture set).
# Budgets: whole-image flash <= 24 KiB for every board build and static RAM + stack peak
# <= 16 KiB (issue 17); <= 500 instructions per inference of the default family's 4-5-3 net
# (issue 29; 1,200 in issue 14); <= 900 per inference of the thesis family's 4-5-3 net (issue 4). Exits 1 if a
# budget is missed.
# Usage: firmware/measure.sh [MODEL_4-5-3.bin [MODEL_9-16-3.bin]]   (default: seeded sample blobs)
# Needs: qemu-system-arm, binutils-arm-none-eabi (apt-get install -y qemu-system-arm binutils-arm-none-eabi).
set -euo pipefail
cd "$(dirname "$0")/.."
for tool in qemu-system-arm arm-none-eabi-objdump arm-none-eabi-nm python3; do
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
INSTR_BUDGET_DEFAULT=500
INSTR_BUDGET_THESIS=900
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

# The host tools are built with the same package selection as the README's `cargo test`
# (every default member, dev units included), so cargo reuses that build instead of building
# the dependencies again with other features (on CI a second copy ran the disk full).
cargo build --quiet --locked --workspace --exclude hvs-firmware --example sample_blob --bin hvs
sample_blob="$target_dir/debug/examples/sample_blob"
small=${1:-}
if [ -z "$small" ]; then
  small="$work/sample-4-5-3.bin"
  "$sample_blob" "$small" 1
fi
posture=${2:-}
if [ -z "$posture" ]; then
  posture="$work/sample-9-16-3.bin"
  "$sample_blob" "$posture" 2 16
fi
default_posture="$work/sample-default-9-16-3.bin"
"$sample_blob" "$default_posture" 2 16 default
default_model="$work/sample-default-4-5-3.bin"
"$sample_blob" "$default_model" 1 default
hvs="$target_dir/debug/hvs"
shape() { "$hvs" info "$1" | sed -n 's/^topology: *\([0-9-]*\).*/\1/p'; }
family() { "$hvs" info "$1" | sed -n 's/^family: *\([a-z-]*\).*/\1/p'; }

# qemu ELF SLOT_A [SLOT_B]: starts QEMU (waiting for the link), sets $port and $qemu_pid.
qemu() {
  local elf=$1 a=$2 b=${3:-}
  port=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
  local loaders=(-device "loader,file=$a,addr=0x080C0000,force-raw=on")
  [ -n "$b" ] && loaders+=(-device "loader,file=$b,addr=0x080E0000,force-raw=on")
  timeout 300 qemu-system-arm -machine netduinoplus2 -display none -monitor none -nodefaults \
    -icount shift=0,sleep=off \
    -serial "tcp:127.0.0.1:$port,server=on,wait=on,nodelay=on" -serial null \
    "${loaders[@]}" -kernel "$elf" 2>/dev/null &
  qemu_pid=$!
}
stop_qemu() { kill "$qemu_pid" 2>/dev/null || true; wait "$qemu_pid" 2>/dev/null || true; qemu_pid=; }
head_cmd() { timeout 120 "$hvs" head --connect "tcp:127.0.0.1:$port" --timeout-ms 20000 "$@"; }

echo "== stack peak reported by the head (QEMU build, after the workload)"
echo "   slot A: $(shape "$small") (generation 1), slot B: $(shape "$posture") (generation 2, runs)"
"$hvs" simulate --case 3 --set volume --points 300 --seed 17 -o "$work/points.csv" >/dev/null
qemu "$work/qemu.elf" "$small" "$posture"
head_cmd info >"$work/info-boot.txt"
head_cmd estimate --points "$work/points.csv" -o "$work/estimates.csv" 2>/dev/null
estimates=$(($(wc -l <"$work/estimates.csv") - 1))
looks=0
for p in "250 300 220 300" "400 200 350 200" "320 240 290 240" "200 260 150 262" "330 241 310 239"; do
  # shellcheck disable=SC2086
  head_cmd look $p >/dev/null && looks=$((looks + 1))
  sleep 0.2
done
head_cmd home >/dev/null
head_cmd info >"$work/info.txt"
stop_qemu
grep -q "slot: B" "$work/info.txt" || { echo "  FAIL: slot B does not run:" >&2; cat "$work/info.txt" >&2; exit 1; }
boot_peak=$(sed -n 's/^stack peak: \([0-9]*\) B$/\1/p' "$work/info-boot.txt")
peak=$(sed -n 's/^stack peak: \([0-9]*\) B$/\1/p' "$work/info.txt")
[ -n "$peak" ] || { echo "  FAIL: no 'stack peak: N B' line in hvs head info" >&2; cat "$work/info.txt" >&2; exit 1; }
static=$(static_ram "$work/qemu.elf")
total=$((static + peak))
ram_verdict="within 16 KiB"; [ "$total" -le "$RAM_BUDGET" ] || ram_verdict="OVER 16 KiB"
echo "   stack peak after boot: $boot_peak B; after $estimates estimates and $looks Looks (+ Home): $peak B"
echo "   static RAM $static B + stack peak $peak B = $total B ($ram_verdict)"

echo "== instructions per inference (QEMU netduinoplus2, -icount shift=0, bench build)"
bench() { # model
  qemu "$work/bench.elf" "$1"
  local out instr
  out=$(head_cmd bench --count 2000)
  stop_qemu
  instr=$(sed -n 's/.*instructions_per_inference_icount0=\([0-9.]*\).*/\1/p' <<<"$out")
  printf '   %-8s %-18s %8s instructions per inference   (%s)\n' "$(shape "$1")" "$(family "$1")" "$instr" "$out" >&2
  echo "$instr"
}
instr_default=$(bench "$default_model")
instr_small=$(bench "$small")
instr_posture=$(bench "$posture")
instr_default_posture=$(bench "$default_posture")

echo "== summary ($(date -u +%Y-%m-%d))"
for b in board pwm qemu; do
  IFS=$'\t' read -r f e _ _ r _ < <(sections "$work/$b.elf")
  printf '   %-6s flash %6d B (image end %d)   static RAM %5d B\n' "$b" "$f" "$e" "$r"
done
echo "   stack peak $peak B; static RAM + stack $total B (budget $RAM_BUDGET)"
echo "   instructions per $(shape "$default_model") $(family "$default_model") inference: $instr_default (default family; budget $INSTR_BUDGET_DEFAULT, issue 29)"
echo "   instructions per $(shape "$small") $(family "$small") inference: $instr_small (budget $INSTR_BUDGET_THESIS for the thesis family, issue 4)"
echo "   instructions per $(shape "$posture") $(family "$posture") inference: $instr_posture; $(family "$default_posture"): $instr_default_posture (posture-aware; no budget)"
# within VALUE BUDGET: whether a (decimal) instruction count is at most the budget.
within() { [ -n "$1" ] && awk -v v="$1" -v b="$2" 'BEGIN { exit !(v <= b) }'; }
status=0
if ! within "$instr_default" "$INSTR_BUDGET_DEFAULT"; then
  echo "FAIL: the default family's $(shape "$default_model") net takes '$instr_default' instructions per inference (budget $INSTR_BUDGET_DEFAULT)" >&2; status=1
fi
if [ "$(family "$small")" = thesis ] && ! within "$instr_small" "$INSTR_BUDGET_THESIS"; then
  echo "FAIL: the thesis family's $(shape "$small") net takes '$instr_small' instructions per inference (budget $INSTR_BUDGET_THESIS)" >&2; status=1
fi
if [ -n "$flash_over" ]; then echo "FAIL: a board build is over 24 KiB of flash" >&2; status=1; fi
if [ "$total" -gt "$RAM_BUDGET" ]; then echo "FAIL: static RAM + stack peak over 16 KiB" >&2; status=1; fi
exit "$status"
