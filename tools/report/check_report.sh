#!/usr/bin/env bash
# Checks an offline HTML report (`regolith validate --report DIR`) in headless Chromium:
#   1. the page loads and every <img> in it decodes in the browser (naturalWidth > 0), read
#      back from the DOM after the load event (--dump-dom on a copy with a checking script);
#   2. every referenced image is a file inside DIR (relative link, no network);
#   3. a full-window screenshot of the page is not blank (PNG decoded with Python's stdlib).
# Usage: tools/report/check_report.sh DIR        (SCREENSHOT=path.png keeps the screenshot)
# Needs chromium (Debian: apt-get install chromium) and python3. Exit 0 ok, 1 check failed,
# 2 usage error or no browser. Not part of CI: the report's own test (cli/tests/report.rs)
# checks the files and sizes without a browser.
set -euo pipefail

dir=${1:-}
if [[ -z "$dir" || ! -f "$dir/index.html" ]]; then
  echo "usage: $0 DIR (DIR/index.html must exist)" >&2
  exit 2
fi
dir=$(cd "$dir" && pwd)
browser=${CHROMIUM:-}
if [[ -z "$browser" ]]; then
  for b in chromium chromium-browser google-chrome; do
    if command -v "$b" >/dev/null 2>&1; then browser=$b; break; fi
  done
fi
if [[ -z "$browser" ]]; then
  echo "no chromium found (apt-get install chromium, or set CHROMIUM=path)" >&2
  exit 2
fi

tmp=$(mktemp -d)
probe="$dir/.check_report_probe.html"
trap 'rm -rf "$tmp" "$probe"' EXIT
flags=(--headless --no-sandbox --disable-gpu --hide-scrollbars --allow-file-access-from-files
       --no-first-run --disable-extensions --user-data-dir="$tmp/profile")

# 1. Load a copy of the page with a script that records, after the load event, each image's
#    decoded size into the DOM; --dump-dom prints the DOM once the page has loaded.
python3 - "$dir/index.html" "$probe" <<'PY'
import sys
html = open(sys.argv[1], encoding="utf-8").read()
script = """<script>
window.addEventListener('load', function () {
  var out = [];
  document.querySelectorAll('img').forEach(function (i) {
    out.push((i.complete && i.naturalWidth > 0 ? 'OK ' : 'BROKEN ') + i.naturalWidth + 'x' +
             i.naturalHeight + ' ' + i.getAttribute('src'));
  });
  var pre = document.createElement('pre');
  pre.id = 'check-report-result';
  pre.textContent = 'IMAGES ' + out.length + '\\n' + out.join('\\n') + '\\nEND';
  document.body.appendChild(pre);
});
</script>"""
if "</body>" not in html:
    sys.exit("index.html has no </body>")
open(sys.argv[2], "w", encoding="utf-8").write(html.replace("</body>", script + "</body>", 1))
PY
"$browser" "${flags[@]}" --virtual-time-budget=20000 --dump-dom "file://$probe" \
  >"$tmp/dom.html" 2>"$tmp/chromium.log" || {
  echo "FAIL: chromium could not load the page:" >&2
  tail -20 "$tmp/chromium.log" >&2
  exit 1
}

# 2 + 3. Read the result block, check the files, take and check a screenshot.
shot=${SCREENSHOT:-$tmp/screenshot.png}
"$browser" "${flags[@]}" --window-size=1400,2400 --screenshot="$shot" "file://$dir/index.html" \
  >>"$tmp/chromium.log" 2>&1 || true

python3 - "$tmp/dom.html" "$dir" "$shot" <<'PY'
import os, re, struct, sys, zlib, html as H

dom_path, root, shot = sys.argv[1:4]
dom = open(dom_path, encoding="utf-8", errors="replace").read()
fail = []
m = re.search(r'<pre id="check-report-result">(.*?)</pre>', dom, re.S)
if not m:
    print("FAIL: the page did not finish loading (no result block in the dumped DOM)")
    sys.exit(1)
lines = H.unescape(m.group(1)).strip().splitlines()
count = int(lines[0].split()[1])
imgs = [l for l in lines[1:] if l != "END"]
if count == 0:
    fail.append("the page has no images")


def png_check(path):
    """Width and height of a PNG whose chunks (CRCs), IEND and whole zlib stream are intact and
    whose decompressed size matches its header (browsers show truncated files partially)."""
    data = open(path, "rb").read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError("not a PNG")
    pos, idat, ihdr, end = 8, b"", None, False
    while pos + 12 <= len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        crc = data[pos + 8 + n:pos + 12 + n]
        if len(body) != n or len(crc) != 4 or struct.unpack(">I", crc)[0] != zlib.crc32(kind + body):
            raise ValueError(f"chunk {kind!r} truncated or corrupt")
        if kind == b"IHDR":
            ihdr = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        elif kind == b"IEND":
            end = True
            break
        pos += 12 + n
    if ihdr is None or not end:
        raise ValueError("no IHDR or IEND")
    w, h, depth, ctype, _, _, interlace = ihdr
    d = zlib.decompressobj()
    raw = d.decompress(idat)
    if not d.eof:
        raise ValueError("image data truncated")
    if interlace == 0:
        channels = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}[ctype]
        stride = (w * channels * depth + 7) // 8
        if len(raw) != h * (stride + 1):
            raise ValueError(f"{len(raw)} bytes of image data for {w}x{h}")
    return w, h


def decode_png(path):
    """Width, height and unfiltered rows of an 8-bit PNG (stdlib only)."""
    data = open(path, "rb").read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError("not a PNG")
    pos, idat, ihdr = 8, b"", None
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        if kind == b"IHDR":
            ihdr = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    w, h, depth, ctype = ihdr[:4]
    if depth != 8:
        raise ValueError(f"bit depth {depth}")
    bpp = {0: 1, 2: 3, 4: 2, 6: 4}[ctype]
    raw, stride, rows, prev = zlib.decompress(idat), w * bpp, [], bytearray(w * bpp)
    for y in range(h):
        f, line = raw[y * (stride + 1)], bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - bpp] if i >= bpp else 0
            b, c = prev[i], (prev[i - bpp] if i >= bpp else 0)
            if f == 1: line[i] = (line[i] + a) & 255
            elif f == 2: line[i] = (line[i] + b) & 255
            elif f == 3: line[i] = (line[i] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        rows.append(bytes(line)); prev = line
    return w, h, bpp, rows

for l in imgs:
    status, size, src = l.split(" ", 2)
    if status != "OK":
        fail.append(f"image did not load in the browser: {src}")
    if re.match(r"^[a-z]+:", src) or src.startswith("/"):
        fail.append(f"image is not a relative link: {src}")
        continue
    path = os.path.normpath(os.path.join(root, src))
    if not path.startswith(root + os.sep) or not os.path.isfile(path):
        fail.append(f"image file missing or outside the report folder: {src}")
        continue
    try:
        w, h = png_check(path)
    except Exception as e:  # noqa: BLE001 - any decoding problem is a failure
        fail.append(f"image does not decode: {src}: {e}")
        continue
    if size != f"{w}x{h}":
        fail.append(f"browser size {size} differs from the file's {w}x{h}: {src}")

if not os.path.isfile(shot):
    fail.append("chromium wrote no screenshot")
else:
    w, h, bpp, rows = decode_png(shot)
    px = {}
    for r in rows[::4]:
        for x in range(0, len(r), bpp * 4):
            k = r[x:x + 3]
            px[k] = px.get(k, 0) + 1
    total = sum(px.values())
    top = max(px.values())
    print(f"screenshot {w}x{h}: {len(px)} colours, {100 * (total - top) / total:.1f}% of pixels differ from the background")
    if len(px) < 16 or (total - top) / total < 0.01:
        fail.append("the screenshot is blank")
print(f"{len(imgs)} images, {sum(1 for l in imgs if l.startswith('OK '))} loaded in chromium")
for f in fail:
    print("FAIL:", f)
if fail:
    sys.exit(1)
print("OK: page and every image load; screenshot not blank")
PY
