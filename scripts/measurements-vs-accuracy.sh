#!/usr/bin/env bash
# Accuracy against measurements used, for both location-selection rules (issue [4/5] item 3):
# sim/paper-fig6.toml at the paper's 0.1 mm, planning-mode divisions at several measurement
# counts per region; Fig. 6 (joint-space division, cap 110) and Fig. 7 (Cartesian division,
# cap 130); mean and max position error of the variable model with and without the FCMAC (and
# of conventional calibration on the same data) along each figure's path.
#
# Counting: a measurement is a location measured once. A half keeps its parent's measurements
# that fall in it and measures only the missing ones, so reused points are not counted again
# ("identification"); the test points each region is checked on are counted apart ("test") and
# in the total. The paper counts identification measurements (2 200 = 110 × 20).
#
# Writes OUT/measurements-vs-accuracy.csv and OUT/measurements-vs-accuracy.svg (the copy in
# docs/ was made with the defaults). Needs jq and python3 (standard library only).
# Usage: scripts/measurements-vs-accuracy.sh [OUT_DIR] [SEED]   (default out/budget, seed 1;
# about two minutes of CPU)
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-out/budget}"
seed="${2:-1}"
per_region_counts="${PER_REGION:-6 8 9 10 12 15 20}"
mkdir -p "$out"
cargo build --release --quiet
rigcal=target/release/rigcal
rig=rigs/rv-m2-ideal.toml
sc=sim/paper-fig6.toml
csv="$out/measurements-vs-accuracy.csv"
echo "selection,figure,division,per_region,regions,identification_measurements,test_measurements,total_measurements,conventional_mean_mm,conventional_max_mm,regions_mean_mm,regions_max_mm,fcmac_mean_mm,fcmac_max_mm" >"$csv"
for selection in kappa d-optimal; do
  for fig in fig6 fig7; do
    division=joint
    [ "$fig" = fig7 ] && division=cartesian
    for n in $per_region_counts; do
      model="$out/$selection-$fig-$n.json"
      figures="$out/$selection-$fig-$n-figures.json"
      $rigcal calibrate --rig $rig --scenario $sc --division $division --selection $selection \
        --per-region "$n" --seed "$seed" --out "$model" >/dev/null
      $rigcal evaluate --model "$model" --scenario $sc --path "$fig" --json "$figures" >/dev/null
      d=$(jq -r '.model.division | "\(.regions),\(.measurements),\(.test_measurements),\(.measurements + .test_measurements)"' "$model")
      m=$(jq -r '[.paths[0].methods[] | select(.method != "uncalibrated")] | map("\(.mean_mm),\(.max_mm)") | join(",")' "$figures")
      echo "$selection,$fig,$division,$n,$d,$m" | tee -a "$csv"
    done
  done
done
python3 - "$csv" "$out/measurements-vs-accuracy.svg" <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
W, H, L, R, T, B = 460, 300, 60, 20, 40, 50
colours = {"kappa": "#1f77b4", "d-optimal": "#d62728"}
def panel(fig, ox):
    rs = [r for r in rows if r["figure"] == fig]
    xs = [float(r["identification_measurements"]) for r in rs]
    x0, x1 = 0.0, max(xs) * 1.05
    y0, y1 = 0.0, 0.2
    sx = lambda x: ox + L + (x - x0) / (x1 - x0) * (W - L - R)
    sy = lambda y: T + (1 - (min(y, y1) - y0) / (y1 - y0)) * (H - T - B)
    name = {"fig6": "Fig. 6 path, joint-space division", "fig7": "Fig. 7 path, Cartesian division"}[fig]
    s = [f'<text x="{ox + W / 2}" y="20" text-anchor="middle" font-size="14">{name}</text>']
    s.append(f'<rect x="{ox + L}" y="{T}" width="{W - L - R}" height="{H - T - B}" fill="none" stroke="#444"/>')
    for k in range(0, 5):
        y = y0 + k * 0.05
        s.append(f'<line x1="{ox + L}" x2="{ox + W - R}" y1="{sy(y)}" y2="{sy(y)}" stroke="#ddd"/>')
        s.append(f'<text x="{ox + L - 6}" y="{sy(y) + 4}" text-anchor="end" font-size="11">{y:.2f}</text>')
    step = 500 if x1 > 1500 else 250
    x = 0
    while x <= x1:
        s.append(f'<text x="{sx(x)}" y="{H - B + 16}" text-anchor="middle" font-size="11">{x}</text>')
        x += step
    s.append(f'<line x1="{ox + L}" x2="{ox + W - R}" y1="{sy(0.1)}" y2="{sy(0.1)}" stroke="#2ca02c" stroke-dasharray="6,3"/>')
    s.append(f'<text x="{ox + W - R - 4}" y="{sy(0.1) - 4}" text-anchor="end" font-size="10" fill="#2ca02c">demanded 0.1 mm</text>')
    s.append(f'<line x1="{sx(1100)}" x2="{sx(1100)}" y1="{T}" y2="{H - B}" stroke="#999" stroke-dasharray="2,3"/>')
    s.append(f'<text x="{sx(1100) + 3}" y="{T + 12}" font-size="10" fill="#666">1 100</text>')
    s.append(f'<text x="{ox + (L + W - R) / 2}" y="{H - 12}" text-anchor="middle" font-size="12">identification measurements (20, 15, … per region)</text>')
    s.append(f'<text x="{ox + 14}" y="{(T + H - B) / 2}" text-anchor="middle" font-size="12" transform="rotate(-90 {ox + 14} {(T + H - B) / 2})">position error, mm</text>')
    for sel, colour in colours.items():
        for method, dash in (("regions", ""), ("fcmac", "5,3")):
            pts = sorted((float(r["identification_measurements"]), float(r[f"{method}_max_mm"]), float(r[f"{method}_mean_mm"])) for r in rs if r["selection"] == sel)
            for idx, style in ((1, 2.0), (2, 1.0)):
                line = " ".join(f"{sx(p[0]):.1f},{sy(p[idx]):.1f}" for p in pts)
                s.append(f'<polyline points="{line}" fill="none" stroke="{colour}" stroke-width="{style}" stroke-dasharray="{dash}"/>')
                for p in pts:
                    s.append(f'<circle cx="{sx(p[0]):.1f}" cy="{sy(p[idx]):.1f}" r="{2.5 if idx == 1 else 1.5}" fill="{colour}"/>')
    return s
parts = panel("fig6", 0) + panel("fig7", W)
legend = []
y = H + 8
for k, (sel, colour) in enumerate(colours.items()):
    for j, (method, dash) in enumerate((("regions", ""), ("fcmac", "5,3"))):
        x = 70 + (2 * k + j) * 210
        legend.append(f'<line x1="{x}" x2="{x + 30}" y1="{y}" y2="{y}" stroke="{colour}" stroke-width="2" stroke-dasharray="{dash}"/>')
        legend.append(f'<text x="{x + 36}" y="{y + 4}" font-size="11">{sel}, {method}</text>')
legend.append(f'<text x="70" y="{y + 22}" font-size="11">thick: max along the path, thin: mean (errors above 0.2 mm drawn at 0.2); sim/paper-fig6.toml, 0.1 mm demanded</text>')
svg = f'<svg xmlns="http://www.w3.org/2000/svg" width="{2 * W}" height="{H + 40}" font-family="sans-serif"><rect width="100%" height="100%" fill="white"/>' + "".join(parts + legend) + "</svg>\n"
open(sys.argv[2], "w").write(svg)
print(f"wrote {sys.argv[1]} and {sys.argv[2]}")
PY
