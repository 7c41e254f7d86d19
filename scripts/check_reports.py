#!/usr/bin/env python3
"""Renders wheelcal's HTML reports in headless Chromium and checks them.

For each `index.html` given: Chromium (Debian's `chromium`) loads a copy of the page with a
small script added that runs once everything has loaded, then measures, at a window 1400 px
wide:
  - no horizontal scroll: document.scrollingElement.scrollWidth <= clientWidth;
  - every plot loads: each <img> is complete with naturalWidth > 0 (SVG and PNG alike);
  - the first screen (1400 x 1000) holds the answer: the page's `.answer` paragraph and
    its first <table> end above 1000 px, before the first plot.
It also writes two screenshots beside the results: NAME-first-screen.png (1400 x 1000)
and NAME-full.png (1400 x the page's height), for a person to look at.

Usage: check_reports.py OUT_DIR NAME=path/to/index.html ...
Exit status 1 when any check fails (each failure is printed). Standard library only.
"""

import json
import os
import re
import shutil
import subprocess
import sys
import tempfile

WIDTH, FIRST_SCREEN = 1400, 1000

PROBE = """
<script>
window.addEventListener('load', () => {
  const se = document.scrollingElement;
  const imgs = Array.from(document.images).map(i => ({
    src: i.getAttribute('src'), complete: i.complete, w: i.naturalWidth,
    top: i.getBoundingClientRect().top + window.scrollY}));
  const box = sel => { const e = document.querySelector(sel);
    return e ? e.getBoundingClientRect().bottom + window.scrollY : null; };
  const r = {scrollWidth: se.scrollWidth, clientWidth: se.clientWidth,
    height: se.scrollHeight, images: imgs, answerBottom: box('.answer'),
    tableBottom: box('table')};
  const pre = document.createElement('pre');
  pre.id = 'wheelcal-check';
  pre.textContent = 'WHEELCAL' + '-CHECK' + JSON.stringify(r) + 'WHEELCAL' + '-END';
  document.body.appendChild(pre);
});
</script>
"""


def chromium():
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    sys.exit("no Chromium: install Debian's chromium (apt-get install -y chromium)")


def run_chromium(args, profile):
    base = [
        chromium(),
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--hide-scrollbars",
        "--disable-dev-shm-usage",
        "--no-first-run",
        "--allow-file-access-from-files",
        f"--user-data-dir={profile}",
        "--virtual-time-budget=10000",
        "--force-device-scale-factor=1",
    ]
    return subprocess.run(
        base + args, capture_output=True, text=True, timeout=180, check=False
    )


def measure(page, profile):
    """Loads a probed copy of `page` (beside it, so its images resolve) and returns the
    probe's measurements."""
    html = open(page, encoding="utf-8").read()
    probed = html.replace("</body>", PROBE + "</body>", 1)
    fd, copy = tempfile.mkstemp(suffix=".html", prefix=".check-", dir=os.path.dirname(page))
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(probed)
        out = run_chromium(
            [f"--window-size={WIDTH},{FIRST_SCREEN}", "--dump-dom", "file://" + copy],
            profile,
        )
    finally:
        os.unlink(copy)
    m = re.search(r"WHEELCAL-CHECK(\{.*?\})WHEELCAL-END", out.stdout, re.S)
    if not m:
        raise RuntimeError(f"{page}: the probe did not report; chromium said: {out.stderr[-2000:]}")
    return json.loads(m.group(1).replace("&quot;", '"').replace("&amp;", "&"))


def screenshot(page, png, height, profile):
    out = run_chromium(
        [f"--window-size={WIDTH},{height}", f"--screenshot={png}", "file://" + page], profile
    )
    if not os.path.exists(png):
        raise RuntimeError(f"{page}: no screenshot; chromium said: {out.stderr[-2000:]}")


def check(name, page, out_dir, profile):
    page = os.path.abspath(page)
    r = measure(page, profile)
    problems = []
    if r["scrollWidth"] > r["clientWidth"]:
        problems.append(
            f"scrolls sideways at {WIDTH} px: scrollWidth {r['scrollWidth']} > clientWidth {r['clientWidth']}"
        )
    if not r["images"]:
        problems.append("no plot on the page")
    for i in r["images"]:
        if not i["complete"] or i["w"] <= 0:
            problems.append(f"image {i['src']} did not load (naturalWidth {i['w']})")
    first_img = min((i["top"] for i in r["images"]), default=None)
    if r["answerBottom"] is None:
        problems.append("no .answer paragraph (the verdict or the factors)")
    elif r["answerBottom"] > FIRST_SCREEN:
        problems.append(f"the answer ends at {r['answerBottom']:.0f} px, below the first screen")
    if r["tableBottom"] is None:
        problems.append("no table")
    elif r["tableBottom"] > FIRST_SCREEN:
        problems.append(f"the first table ends at {r['tableBottom']:.0f} px, below the first screen")
    if first_img is not None and r["answerBottom"] is not None and first_img < r["answerBottom"]:
        problems.append("a plot comes before the answer")
    screenshot(page, os.path.join(out_dir, f"{name}-first-screen.png"), FIRST_SCREEN, profile)
    full = max(FIRST_SCREEN, min(int(r["height"]) + 20, 30000))
    screenshot(page, os.path.join(out_dir, f"{name}-full.png"), full, profile)
    status = "ok" if not problems else "FAILED"
    print(
        f"{name}: {status}: scrollWidth {r['scrollWidth']} / clientWidth {r['clientWidth']}, "
        f"{sum(1 for i in r['images'] if i['w'] > 0)}/{len(r['images'])} images loaded, "
        f"answer ends at {r['answerBottom']}, first table at {r['tableBottom']}, page {r['height']} px"
    )
    for p in problems:
        print(f"  {name}: {p}")
    return not problems


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    out_dir = sys.argv[1]
    os.makedirs(out_dir, exist_ok=True)
    ok = True
    with tempfile.TemporaryDirectory(prefix="wheelcal-chromium-") as profile:
        for arg in sys.argv[2:]:
            name, _, page = arg.partition("=")
            try:
                ok &= check(name, page, out_dir, profile)
            except (RuntimeError, subprocess.TimeoutExpired) as e:
                print(f"{name}: FAILED: {e}")
                ok = False
    print("all reports pass" if ok else "some reports FAILED")
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
