#!/usr/bin/env bash
# Table III on an emulated Cortex-M7: installs Debian's Rust, QEMU and LLVM if missing, builds
# the firmware, runs every case on QEMU's mps2-an500 (checking each case's estimates against
# the host's, bit for bit), counts executed instructions per update with an instruction-counting
# QEMU plugin (its measure.sh wrapper, not part of the repository), converts them to an
# ESTIMATE of cycles with llvm-mca's Cortex-M7 model, and prints the table.
#
# Exit status: non-zero if the build fails, a case fails or its checksum differs from the
# host's. Writes the final table to firmware/target/table3.md, and the arm cases' (n = 10 and
# 70, m = 70) to firmware/target/arm.md. Environment:
#   TAGK_MCU_SKIP_INSTALL=1   do not call apt-get (everything must already be installed)
#   TAGK_MCU_MEASURE=path     measure.sh to use (unset: instruction counts are skipped)
set -euo pipefail

FW=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
LLVM_BIN=/usr/lib/llvm-22/bin
PACKAGES=(rustc-web cargo-web rust-web-src rust-web-llvm lld-22 llvm-22 qemu-system-arm gcc)
R1=2 R2=6   # timed updates of the two runs whose difference gives one update's cost
PAPER_SPEEDUP=([40]=4.7 [120]=20.7)
CLOCK_MHZ=600

log() { printf '[tagk-mcu run.sh] %s\n' "$*" >&2; }

# --- 1. Tools --------------------------------------------------------------------------------
missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  if [[ ${TAGK_MCU_SKIP_INSTALL:-0} == 1 ]]; then
    log "missing packages: ${missing[*]} (TAGK_MCU_SKIP_INSTALL=1)"; exit 1
  fi
  SUDO=(); [[ $(id -u) -ne 0 ]] && SUDO=(sudo -n)
  log "installing ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  "${SUDO[@]}" apt-get update -qq
  "${SUDO[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# --- 2. Build (Debian's Rust 1.96 with its library source: -Zbuild-std=core) ----------------
export RUSTC_BOOTSTRAP=1 RUSTC=/usr/bin/rustc RUSTDOC=/usr/bin/rustdoc
unset RUSTUP_TOOLCHAIN RUSTFLAGS CARGO_BUILD_TARGET CARGO_TARGET_DIR || true
log "building the firmware ($(/usr/bin/rustc --version))"
(cd "$FW" && /usr/bin/cargo build --release --quiet)
ELF=$FW/target/thumbv7em-none-eabihf/release/tagk-mcu-firmware
OUT=$FW/target/table3
rm -rf "$OUT"; mkdir -p "$OUT"

# --- 3. The instruction-counting plugin ------------------------------------------------------
MEASURE=${TAGK_MCU_MEASURE:-}
QEMU=(qemu-system-arm -cpu cortex-m7 -machine mps2-an500 -nographic
      -semihosting-config enable=on,target=native -kernel "$ELF")

# --- 4. Every case once, checked against the host --------------------------------------------
log "running every case on QEMU mps2-an500 (Cortex-M7)"
status=0
(cd "$OUT" && "${QEMU[@]}") | tee "$OUT/firmware.txt" || status=$?
if ((status != 0)); then
  log "the firmware reported a failure (exit status $status)"; exit "$status"
fi
if [[ -z $MEASURE || ! -f $MEASURE ]]; then
  log "instruction counts skipped: no measure.sh (set TAGK_MCU_MEASURE=/path/to/measure.sh,"
  log "the instruction-counting plugin's wrapper, not part of the repository). Checksums passed."
  exit 0
fi

# --- 5. Executed instructions per update: run each case with R1 and R2 timed updates --------
# Table III's 30 cases, then the arm cases (tagk_mcu::ARM_CASES), numbered after them.
NCASES=$(grep -c ' ok$' "$OUT/firmware.txt")
log "counting instructions: $NCASES cases x 2 runs"
count() { # case reps -> total executed instructions (the case's checksum must pass)
  local dir=$OUT/case-$1-$2 total
  mkdir -p "$dir"; printf '%s %s\n' "$1" "$2" > "$dir/tagk-mcu-case.txt"
  (cd "$dir" && sh "$MEASURE" "$ELF" > out.txt 2>&1) || { cat "$dir/out.txt" >&2; return 1; }
  grep -q ' ok$' "$dir/out.txt" || { cat "$dir/out.txt" >&2; return 1; }
  total=$(sed -n 's/^insns total: //p' "$dir/out.txt")
  [[ -n $total ]] || { log "no instruction count in $dir/out.txt"; return 1; }
  echo "$total"
}
: > "$OUT/counts.txt"
for idx in $(seq 0 $((NCASES - 1))); do
  c1=$(count "$idx" $R1); c2=$(count "$idx" $R2)
  # label n precision, from the firmware's row: "IDX LABEL N M PREC ..."
  read -r _ label n _ prec _ < "$OUT/case-$idx-$R1/out.txt"
  echo "$idx $label $n $prec $(( (c2 - c1) / (R2 - R1) ))" >> "$OUT/counts.txt"
done

# --- 6. Instructions -> cycles: llvm-mca on each update's hottest inner loop -----------------
# The hottest loop is taken to be the innermost loop with the most FP multiply(-accumulate)
# instructions in the estimator's update function (a dot-product or Gram kernel).
hot_loop() { # demangled-symbol substring -> llvm-mca input on stdout
  "$LLVM_BIN/llvm-objdump" -d -C --mcpu=cortex-m7 --no-show-raw-insn "$ELF" | awk -v sym="$1" '
    function hex(s,   i, v) {  # "0x1f" or "1f" -> 31 (mawk has no strtonum)
      sub(/^0x/, "", s); v = 0
      for (i = 1; i <= length(s); i++) v = v * 16 + index("0123456789abcdef", substr(s, i, 1)) - 1
      return v
    }
    /^[0-9a-f]+ <.*>:$/ { infn = index($0, sym) > 0; next }
    infn && /^ +[0-9a-f]+:/ {
      addr = hex(substr($1, 1, length($1) - 1)); line = $0
      sub(/^ +[0-9a-f]+:[ \t]+/, "", line); sub(/[ \t]*@.*$/, "", line)
      n++; A[n] = addr; L[n] = line
      if (line ~ /^b[a-z]*(\.w)?[ \t]+0x[0-9a-f]+/) {
        split(line, f, /[ \t]+/); t = hex(f[2])
        if (t < addr) { nb++; BS[nb] = t; BE[nb] = addr }
      }
    }
    END {
      best = 0
      for (k = 1; k <= nb; k++) {
        inner = 1; fp = 0
        for (j = 1; j <= nb; j++) if (j != k && BS[j] >= BS[k] && BE[j] < BE[k]) inner = 0
        if (!inner) continue
        for (i = 1; i <= n; i++) if (A[i] >= BS[k] && A[i] <= BE[k] && L[i] ~ /^v(mla|mls|fma|fms|mul)\./) fp++
        if (fp > best) { best = fp; bk = k }
      }
      if (!best) exit 1
      # llvm-mca does not follow branches: the back edge jumps to .Lhot, exits to .Lend.
      print ".Lhot:"
      for (i = 1; i <= n; i++) if (A[i] >= BS[bk] && A[i] <= BE[bk]) {
        line = L[i]
        sub(/0x[0-9a-f]+ <.*$/, (A[i] == BE[bk]) ? ".Lhot" : ".Lend", line)
        print line
      }
      print ".Lend:"
    }'
}
factor() { # symbol-substring name -> cycles per instruction of the hot loop
  hot_loop "$1" > "$OUT/$2.s" || { echo "n/a"; return; }
  "$LLVM_BIN/llvm-mca" -mtriple=thumbv7em-none-eabihf -mcpu=cortex-m7 -iterations=200 \
    "$OUT/$2.s" > "$OUT/$2.mca.txt" 2>&1 || { echo "n/a"; return; }
  awk '/^Instructions:/ {i = $2} /^Total Cycles:/ {c = $3} END {printf "%.3f", c / i}' "$OUT/$2.mca.txt"
}
F_TAGK64=$(factor "McuEstimator<f64> as tagk_core::estimator::OnlineEstimator>::update" tagk-f64)
F_TAGK32=$(factor "McuEstimator<f32> as tagk_core::estimator::OnlineEstimator<f32>>::update" tagk-f32)
F_COV64=$(factor "BlockFilter<f64, &mut [f64]>>::update" cov-f64)
F_COV32=$(factor "BlockFilter<f32, &mut [f32]>>::update" cov-f32)
log "llvm-mca cycles/instruction on the hottest loop: TAG-K f64 $F_TAGK64, f32 $F_TAGK32; RLS/KF f64 $F_COV64, f32 $F_COV32"

# --- 7. The table ----------------------------------------------------------------------------
awk -v ft64="$F_TAGK64" -v ft32="$F_TAGK32" -v fc64="$F_COV64" -v fc32="$F_COV32" \
    -v mhz=$CLOCK_MHZ -v p40="${PAPER_SPEEDUP[40]}" -v p120="${PAPER_SPEEDUP[120]}" '
  { key = $3 " " $4; if ($2 == "TAG-K") t[key] = $5; else if ($2 ~ /^RLS/) r[key] = $5; else { k[key] = $5; kl[$4] = $2 }
    ns[$3] = 1; ps[$4] = 1 }
  function est(ins, f) { return (f == "n/a") ? "n/a" : sprintf("%.0f", ins * f) }
  function us(ins, f) { return (f == "n/a") ? "n/a" : sprintf("%.0f", ins * f / mhz) }
  END {
    print "Executed instructions per update (QEMU mps2-an500, exact), m = 30; cycles and µs at " mhz " MHz are an ESTIMATE"
    print "(instructions x llvm-mca -mcpu=cortex-m7 cycles/instruction of the update'"'"'s hottest loop:"
    print " TAG-K f64 " ft64 ", f32 " ft32 "; RLS/KF f64 " fc64 ", f32 " fc32 ")."
    print ""
    print "| prec | n | RLS-low instr | KF instr | TAG-K instr | speedup vs RLS | speedup vs KF | paper speedup | TAG-K est. cycles | TAG-K est. µs | RLS est. µs | KF est. µs |"
    print "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
    split("f64 f32", P, " "); split("40 60 80 100 120", N, " ")
    for (pi = 1; pi <= 2; pi++) for (ni = 1; ni <= 5; ni++) {
      p = P[pi]; n = N[ni]; key = n " " p
      ft = (p == "f64") ? ft64 : ft32; fc = (p == "f64") ? fc64 : fc32
      paper = (n == 40) ? p40 "×" : (n == 120) ? p120 "×" : "—"
      printf "| %s | %d | %d | %d (%s) | %d | %.1f× | %.1f× | %s | %s | %s | %s | %s |\n", p, n, r[key], k[key], kl[p], t[key],
        r[key] / t[key], k[key] / t[key], paper, est(t[key], ft), us(t[key], ft), us(r[key], fc), us(k[key], fc)
    }
  }' <(head -n 30 "$OUT/counts.txt") | tee "$FW/target/table3.md"

# --- 8. The arm cases: n = 10 (payload) and 70 (every link of a 7-joint arm), m = 70 --------
echo
tail -n +31 "$OUT/counts.txt" | awk -v ft64="$F_TAGK64" -v ft32="$F_TAGK32" -v fc64="$F_COV64" \
    -v fc32="$F_COV32" -v mhz=$CLOCK_MHZ '
  { key = $3 " " $4; if ($2 == "TAG-K") t[key] = $5; else if ($2 ~ /^RLS/) r[key] = $5; else k[key] = $5 }
  function us(ins, f) { return (f == "n/a" || ins == "") ? "—" : sprintf("%.0f", ins * f / mhz) }
  function num(x) { return (x == "") ? "—" : x }
  END {
    print "Arm cases: executed instructions per update (QEMU mps2-an500, exact), m = 70 (10 samples x 7 joints);"
    print "µs at " mhz " MHz are an ESTIMATE (same llvm-mca factors as above). KF: KF-high, f64 only."
    print ""
    print "| prec | n | RLS-low instr | KF-high instr | TAG-K instr | speedup vs RLS | TAG-K est. µs | RLS est. µs | KF est. µs |"
    print "|---|---:|---:|---:|---:|---:|---:|---:|---:|"
    split("f64 f32", P, " "); split("10 70", N, " ")
    for (pi = 1; pi <= 2; pi++) for (ni = 1; ni <= 2; ni++) {
      p = P[pi]; n = N[ni]; key = n " " p
      ft = (p == "f64") ? ft64 : ft32; fc = (p == "f64") ? fc64 : fc32
      printf "| %s | %d | %s | %s | %s | %.1f× | %s | %s | %s |\n", p, n, num(r[key]), num(k[key]), num(t[key]),
        r[key] / t[key], us(t[key], ft), us(r[key], fc), us(k[key], fc)
    }
  }' | tee "$FW/target/arm.md"

# A closing line in the form CI logs recognise: every case ran and matched the host.
echo "tagk-mcu firmware: $(grep -c ' ok$' "$OUT/firmware.txt") passed, $(grep -c 'FAILED' "$OUT/firmware.txt") failed"
