#!/usr/bin/env bash
# Executed instructions per update of TAG-K (f64 and f32), RLS-low and KF-low at n = 10 and 120,
# m = 30, on the Table III windows: the speed figure that does not move with the machine's load.
#
#   bash tagk-insncount/run.sh x86       callgrind on an x86-64 release build; valgrind does
#                                        not emulate AVX-512, so this counts the AVX2 kernels
#   bash tagk-insncount/run.sh aarch64   a cross build (Debian's Rust with -Zbuild-std, linker
#                                        gcc-aarch64-linux-gnu) run under qemu-aarch64 (user
#                                        mode) with an instruction-counting TCG plugin: NEON
#   bash tagk-insncount/run.sh all       both (the default)
#
# Each case runs twice, with U1 and U2 updates; (count(U2) − count(U1)) / (U2 − U1) is one
# update's cost, start-up and window generation cancelling. Every run prints a fingerprint of
# all estimates' bits: the script fails if the x86-64 binary natively (AVX-512 where the CPU
# has it), under callgrind (AVX2) and the aarch64 binary (NEON) print different ones.
#
# Each architecture's counts are compared with the committed baseline-<arch>.txt beside this
# script: the run fails when a TAG-K count exceeds its baseline by more than 5 %. Tables go to
# <target>/insncount/<arch>.md, where <target> is cargo's target directory (CARGO_TARGET_DIR
# or the workspace's target/, as `cargo metadata` reports it); nothing else is written but a
# blessed baseline. Environment:
#   TAGK_INSNCOUNT_BLESS=1        write the measured counts as the new baselines
#   TAGK_INSNCOUNT_SKIP_INSTALL=1 never call apt-get
#   TAGK_INSNCOUNT_PLUGIN_SRC     insncount.c of an instruction-counting QEMU plugin (CI
#                                 passes the development machines' Cortex-M7 one; unset,
#                                 aarch64 checks bits but counts nothing)
#   TAGK_KERNELS=portable         count the portable kernels instead (tagk-core reads it; the
#                                 tables go to <arch>-portable.md, no baseline is checked)
#   TAGK_INSNCOUNT_OUT            where the tables go (default <target>/insncount)
set -euo pipefail

HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
ROOT=$(cd "$HERE/.." && pwd)
# Cargo's target directory, wherever CARGO_TARGET_DIR or a config puts it.
TARGET=$(cd "$ROOT" && cargo metadata --format-version 1 --no-deps --offline 2>/dev/null \
  | grep -o '"target_directory":"[^"]*"' | cut -d'"' -f4)
[[ -n $TARGET ]] || TARGET=${CARGO_TARGET_DIR:-$ROOT/target}
OUT=${TAGK_INSNCOUNT_OUT:-$TARGET/insncount}
U1=20 U2=60
CASES=("tagk 10" "tagk 120" "tagk-f32 10" "tagk-f32 120" "rls-low 10" "rls-low 120" "kf-low 10" "kf-low 120")
TOLERANCE_PERCENT=5
WHAT=${1:-all}
export CARGO_INCREMENTAL=0

log() { printf '[tagk-insncount] %s\n' "$*" >&2; }
mkdir -p "$OUT"

install() { # packages... : apt-get install those not installed yet
  local missing=() p
  for p in "$@"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "ok installed" || missing+=("$p")
  done
  ((${#missing[@]})) || return 0
  if [[ ${TAGK_INSNCOUNT_SKIP_INSTALL:-0} == 1 ]]; then
    log "missing packages: ${missing[*]} (TAGK_INSNCOUNT_SKIP_INSTALL=1)"; exit 1
  fi
  local sudo=(); [[ $(id -u) -ne 0 ]] && sudo=(sudo -n)
  log "installing ${missing[*]}"
  DEBIAN_FRONTEND=noninteractive "${sudo[@]}" apt-get update -qq
  DEBIAN_FRONTEND=noninteractive "${sudo[@]}" apt-get install -y -qq --no-install-recommends \
    "${missing[@]}" >/dev/null
}

# count ARCH RUNNER... -- ARGS: runs the binary with ARGS, prints "COUNT FINGERPRINT-LINE".
count_callgrind() { # bin args...
  local err line
  err=$(mktemp)
  line=$(valgrind --tool=callgrind --callgrind-out-file=/dev/null "$@" 2>"$err") || {
    cat "$err" >&2; return 1; }
  echo "$(sed -n 's/.*Collected : //p' "$err") $line"
  rm -f "$err"
}
count_qemu() { # bin args...
  local err line
  err=$(mktemp)
  line=$(qemu-aarch64 -L /usr/aarch64-linux-gnu -plugin "$PLUGIN" -d plugin -D "$err" "$@") || {
    cat "$err" >&2; return 1; }
  echo "$(sed -n 's/^insns total: //p' "$err") $line"
  rm -f "$err"
}
run_qemu() { qemu-aarch64 -L /usr/aarch64-linux-gnu "$@"; }

# measure ARCH COUNTER BIN: per-update counts of every case into $OUT/ARCH.txt, and the
# fingerprint lines of the U2 runs into $OUT/ARCH.bits.
measure() {
  local arch=$1 counter=$2 bin=$3 c est n r1 r2
  : > "$OUT/$arch.txt"; : > "$OUT/$arch.bits"
  for c in "${CASES[@]}"; do
    read -r est n <<< "$c"
    r1=$($counter "$bin" "$est" "$n" $U1)
    r2=$($counter "$bin" "$est" "$n" $U2)
    echo "$est $n $(( (${r2%% *} - ${r1%% *}) / (U2 - U1) ))" >> "$OUT/$arch.txt"
    echo "${r2#* }" >> "$OUT/$arch.bits"
  done
}

# check ARCH LABEL: the table, the baseline check (or bless).
check() {
  local arch=$1 label=$2 base=$HERE/baseline-$1.txt
  if [[ -n ${TAGK_KERNELS:-} ]]; then
    label="$label, TAGK_KERNELS=$TAGK_KERNELS"
    cp "$OUT/$arch.txt" "$OUT/$arch-$TAGK_KERNELS.txt"
    arch=$arch-$TAGK_KERNELS
  fi
  awk -v label="$label" '
    { c[$1 " " $2] = $3 }
    END {
      print "Executed instructions per update, m = 30 (" label "; tagk-insncount/run.sh)."
      print ""
      print "| n | TAG-K f64 | TAG-K f32 | RLS-low f64 | KF-low f64 | RLS-low / TAG-K | KF-low / TAG-K |"
      print "|---:|---:|---:|---:|---:|---:|---:|"
      split("10 120", N, " ")
      for (i = 1; i <= 2; i++) { n = N[i]; t = c["tagk " n]
        printf "| %d | %d | %d | %d | %d | %.2f× | %.2f× |\n", n, t, c["tagk-f32 " n], c["rls-low " n],
          c["kf-low " n], c["rls-low " n] / t, c["kf-low " n] / t }
    }' "$OUT/$arch.txt" | tee "$OUT/$arch.md"
  if [[ -n ${TAGK_KERNELS:-} ]]; then
    log "TAGK_KERNELS=$TAGK_KERNELS: no baseline check"; return 0
  fi
  if [[ ${TAGK_INSNCOUNT_BLESS:-0} == 1 ]]; then
    { echo "# estimator n instructions-per-update ($label; tagk-insncount/run.sh; TAGK_INSNCOUNT_BLESS=1 rewrites)"
      cat "$OUT/$arch.txt"; } > "$base"
    log "baseline written: $base"; return 0
  fi
  [[ -f $base ]] || { log "no baseline $base (run with TAGK_INSNCOUNT_BLESS=1)"; return 1; }
  awk -v tol=$TOLERANCE_PERCENT '
    NR == FNR { if ($1 !~ /^#/) b[$1 " " $2] = $3; next }
    $1 ~ /^tagk/ {
      key = $1 " " $2
      if (!(key in b)) { printf "%s: no baseline\n", key; bad = 1; next }
      pct = 100 * ($3 - b[key]) / b[key]
      printf "%-14s %9d instructions/update, baseline %9d (%+.1f %%)\n", key, $3, b[key], pct
      if (pct > tol) { printf "  more than %d %% over the baseline\n", tol; bad = 1 }
    }
    END { exit bad }' "$base" "$OUT/$arch.txt"
}

# --- x86-64: callgrind (the AVX2 kernels) ---------------------------------------------------
X86_BIN=$TARGET/release/tagk-insncount
# The host build, and its fingerprints run natively (the CPU's best kernels: AVX-512 where it
# has it) into $OUT/x86_64-native.bits.
native() {
  log "building tagk-insncount (release)"
  (cd "$ROOT" && cargo build --release --quiet -p tagk-insncount)
  local c est n
  : > "$OUT/x86_64-native.bits"
  for c in "${CASES[@]}"; do
    read -r est n <<< "$c"
    "$X86_BIN" "$est" "$n" $U2 >> "$OUT/x86_64-native.bits"
  done
}

x86() {
  install valgrind
  native
  log "counting with callgrind (valgrind hides AVX-512: the AVX2 kernels run)"
  measure x86_64 count_callgrind "$X86_BIN"
  if ! cmp -s "$OUT/x86_64.bits" "$OUT/x86_64-native.bits"; then
    log "native and callgrind runs computed different bits:"
    diff "$OUT/x86_64-native.bits" "$OUT/x86_64.bits" >&2 || true
    return 1
  fi
  if [[ -n ${TAGK_KERNELS:-} ]]; then
    log "native and callgrind runs (TAGK_KERNELS=$TAGK_KERNELS): the same bits"
  else
    log "native ($(grep -q avx512f /proc/cpuinfo && echo AVX-512 || echo AVX2) kernels) and callgrind (AVX2) runs: the same bits"
  fi
  local kernels="AVX2 kernels"
  [[ ${TAGK_KERNELS:-} == portable ]] && kernels="portable kernels"
  check x86_64 "x86-64 $kernels under valgrind's callgrind"
}

# --- aarch64: cross build, QEMU user mode (the NEON kernels) --------------------------------
aarch64() {
  install rustc-web cargo-web rust-web-src gcc-aarch64-linux-gnu libc6-dev-arm64-cross qemu-user gcc
  log "cross-building tagk-insncount for aarch64 ($(/usr/bin/rustc --version), -Zbuild-std)"
  (
    cd "$ROOT"
    export RUSTC_BOOTSTRAP=1 RUSTC=/usr/bin/rustc RUSTDOC=/usr/bin/rustdoc
    export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_LINKER=aarch64-linux-gnu-gcc
    unset RUSTUP_TOOLCHAIN RUSTFLAGS CARGO_BUILD_TARGET CARGO_TARGET_DIR || true
    /usr/bin/cargo build --release --quiet -p tagk-insncount --target aarch64-unknown-linux-gnu \
      -Zbuild-std=std,panic_abort --target-dir "$TARGET/aarch64"
  )
  # tagk-core's own test of the SIMD kernels against the portable ones, bit for bit (many
  # window shapes, f64 and f32), run on the NEON kernels under qemu-aarch64.
  log "tagk-core's kernel tests on aarch64 (qemu-aarch64)"
  (
    cd "$ROOT"
    export RUSTC_BOOTSTRAP=1 RUSTC=/usr/bin/rustc RUSTDOC=/usr/bin/rustdoc
    export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_LINKER=aarch64-linux-gnu-gcc
    export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_RUNNER="qemu-aarch64 -L /usr/aarch64-linux-gnu"
    unset RUSTUP_TOOLCHAIN RUSTFLAGS CARGO_BUILD_TARGET CARGO_TARGET_DIR || true
    /usr/bin/cargo test --release --quiet -p tagk-core --lib --target aarch64-unknown-linux-gnu \
      -Zbuild-std=std,panic_abort --target-dir "$TARGET/aarch64"
  )
  local bin=$TARGET/aarch64/aarch64-unknown-linux-gnu/release/tagk-insncount c est n
  local src=${TAGK_INSNCOUNT_PLUGIN_SRC:-}
  if [[ -n $src && -f $src ]]; then
    # The Cortex-M7 tool's plugin, built for the installed QEMU (user-mode plugins load alike).
    local major def=""
    major=$(qemu-aarch64 --version | sed -n 's/.*version \([0-9]*\)\..*/\1/p;q')
    [[ $major -ge 9 ]] && def=-DQEMU_PLUGIN_API2
    PLUGIN=$OUT/libinsncount-q$major.so
    gcc -O2 -shared -fPIC $def -o "$PLUGIN" "$src"
    log "counting under qemu-aarch64 $major with the insncount plugin"
    measure aarch64 count_qemu "$bin"
  else
    log "no QEMU plugin source (TAGK_INSNCOUNT_PLUGIN_SRC): checking bits only, no counts"
    : > "$OUT/aarch64.bits"
    for c in "${CASES[@]}"; do
      read -r est n <<< "$c"
      run_qemu "$bin" "$est" "$n" $U2 >> "$OUT/aarch64.bits"
    done
  fi
  [[ -f $OUT/x86_64-native.bits && $WHAT == all ]] || native
  # TAG-K must compute the same bits everywhere. RLS-low and KF-low run faer's products, whose
  # kernels differ per architecture (FMA on aarch64): close, not bit-identical.
  if ! cmp -s <(grep '^tagk' "$OUT/aarch64.bits") <(grep '^tagk' "$OUT/x86_64-native.bits"); then
    log "TAG-K on aarch64 and x86-64 computed different bits:"
    diff "$OUT/x86_64-native.bits" "$OUT/aarch64.bits" >&2 || true
    return 1
  fi
  log "aarch64 (${TAGK_KERNELS:-NEON} kernels, QEMU) and x86-64: TAG-K the same bits in every case; RLS/KF (faer):"
  paste -d' ' <(grep -v '^tagk' "$OUT/x86_64-native.bits" | sed 's/.*sum=/x86-64 sum=/') \
    <(grep -v '^tagk' "$OUT/aarch64.bits" | sed 's/.*sum=/aarch64 sum=/') >&2
  if [[ -n $src && -f $src ]]; then
    local kernels="NEON kernels"
    [[ ${TAGK_KERNELS:-} == portable ]] && kernels="portable kernels"
    check aarch64 "aarch64 $kernels under qemu-aarch64 $(qemu-aarch64 --version | sed -n 's/.*version \([0-9.]*\).*/\1/p;q'), insncount plugin"
  fi
}

case $WHAT in
  x86) x86 ;;
  aarch64) aarch64 ;;
  all) x86; aarch64 ;;
  *) echo "usage: $0 [x86|aarch64|all]" >&2; exit 2 ;;
esac
# A closing line in the form CI logs recognise.
echo "tagk-insncount ($WHAT): ${#CASES[@]} passed, 0 failed"
