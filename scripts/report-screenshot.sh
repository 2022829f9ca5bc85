#!/usr/bin/env bash
# Opens a rigcal HTML report in a headless browser and saves a PNG screenshot of the whole page.
#   scripts/report-screenshot.sh r.html [r.png] [width]
# Uses the first of chromium / chromium-browser / google-chrome / firefox found on PATH, else
# Python's playwright (with its own browser). The report needs no network: it is one file with
# inline CSS and SVG.
set -euo pipefail
html=${1:?usage: report-screenshot.sh REPORT.html [OUT.png] [WIDTH]}
png=${2:-${html%.html}.png}
width=${3:-1200}
[ -f "$html" ] || { echo "no such file: $html" >&2; exit 1; }
url="file://$(cd "$(dirname "$html")" && pwd)/$(basename "$html")"
for b in chromium chromium-browser google-chrome google-chrome-stable; do
  if command -v "$b" >/dev/null; then
    timeout 60 "$b" --headless --disable-gpu --no-sandbox --hide-scrollbars \
      --window-size="$width,4000" --screenshot="$png" "$url"
    echo "screenshot written to $png ($b)"; exit 0
  fi
done
if command -v firefox >/dev/null; then
  timeout 60 firefox --headless --window-size "$width,4000" --screenshot "$png" "$url"
  echo "screenshot written to $png (firefox)"; exit 0
fi
if python3 -c 'import playwright' 2>/dev/null; then
  timeout 120 python3 - "$url" "$png" "$width" <<'PY'
import sys
from playwright.sync_api import sync_playwright
url, png, width = sys.argv[1], sys.argv[2], int(sys.argv[3])
with sync_playwright() as p:
    b = p.chromium.launch()
    page = b.new_page(viewport={"width": width, "height": 900})
    page.goto(url)
    page.screenshot(path=png, full_page=True)
    b.close()
PY
  echo "screenshot written to $png (playwright)"; exit 0
fi
cat >&2 <<'MSG'
No headless browser found. Install one of:
  sudo apt-get install chromium        (Debian/Ubuntu; or chromium-browser)
  sudo apt-get install firefox-esr
  pip install playwright && python3 -m playwright install chromium
then run this script again. (The report itself opens in any browser: it is self-contained.)
MSG
exit 2
