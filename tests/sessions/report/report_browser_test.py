#!/usr/bin/python3
"""The calibration report in a real browser (issue 18).

Usage: report_browser_test.py MSMCAL_BINARY OUT_DIR  (run in its own network namespace: the demo
rig serves GigE Vision on 127.0.0.1:3956).

Runs a small simulated demo session (`msmcal demo`, 4 sliding-plate poses, 18 triggers, 2 s Hall
recordings), regenerates its report with `msmcal report` (the session's provenance kept), builds
a one-point sweep folder around it and writes the sweep report, then opens both reports in
headless Chromium (selenium + /usr/bin/chromedriver) and checks: no console error, no network
request, the verdict first and non-empty, every plot canvas drawn (non-blank pixels, data in each
chart), the HTML tables, the held-out residual vectors drawn with their scale, the whitened
residuals' histogram, the provenance with the commit the binary was built from, zoom by drag
and reset by double-click, the sweep report's link to the point's report. Screenshots go to
OUT_DIR/report.png and OUT_DIR/sweep_report.png.

Exit 77 (ctest: skipped) with a message when chromium, chromedriver or python3-selenium is
missing. No sleeps: waits are on page conditions with a deadline.
"""
import json
import os
import shutil
import subprocess
import sys

SKIP = 77

SIM = """\
seed: 3
step1:
  poses: 4
step2:
  neutral_frames: 1
  fast_only_frames: 2
triggers:
  max_triggers: 18
hall:
  background_duration_s: 2
  actual_duration_s: 2
"""

PLAN = """\
note: report browser test (tiny simulator)
base:
""" + "".join("  " + line + "\n" for line in SIM.splitlines()) + """\
axes:
  hall.noise_uT: [1.5]
"""


def fail(msg):
    print("FAIL: " + msg, flush=True)
    sys.exit(1)


def run(cmd, **kw):
    print("$ " + " ".join(cmd), flush=True)
    r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, **kw)
    return r


def open_browser():
    for tool in ("/usr/bin/chromium", "/usr/bin/chromedriver"):
        if not os.path.exists(tool):
            print("SKIPPED: %s missing (Debian packages chromium, chromium-driver: scripts/setup)"
                  % tool, flush=True)
            sys.exit(SKIP)
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError:
        print("SKIPPED: python3-selenium missing (Debian package python3-selenium)", flush=True)
        sys.exit(SKIP)
    options = webdriver.ChromeOptions()
    options.binary_location = "/usr/bin/chromium"
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--window-size=1400,1000", "--no-first-run", "--disable-extensions"):
        options.add_argument(arg)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    return webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=options)


def wait_for(driver, script, what, timeout=30):
    from selenium.webdriver.support.ui import WebDriverWait
    try:
        WebDriverWait(driver, timeout).until(lambda d: d.execute_script(script))
    except Exception as e:  # selenium's TimeoutException
        fail("page condition not met within %d s: %s (%s)" % (timeout, what, type(e).__name__))


# Per canvas: does its chart exist, with data, and how many non-blank pixels does it show.
CANVAS_STATE = """
return Array.from(document.querySelectorAll('canvas.msmcal-plot')).map(c => {
  const chart = (window.msmcalCharts || {})[c.id];
  const ctx = c.getContext('2d');
  const img = ctx.getImageData(0, 0, c.width, c.height).data;
  let ink = 0;
  for (let i = 0; i < img.length; i += 4) {
    if (img[i + 3] > 0 && (img[i] < 235 || img[i + 1] < 235 || img[i + 2] < 235)) ink++;
  }
  const points = chart ? chart.data.datasets.reduce((n, d) => n + d.data.filter(
      p => p !== null && (typeof p === 'number' || (p && p.y !== null))).length, 0) : 0;
  return {id: c.id, chart: !!chart, points: points, ink: ink, w: c.width, h: c.height};
});
"""


def check_page(driver, path, screenshot, expect_tables, min_plots):
    driver.get("file://" + path)
    wait_for(driver, "return document.readyState === 'complete' && window.msmcalCharts !== "
             "undefined", "charts drawn")
    errors = [e for e in driver.get_log("browser") if e.get("level") == "SEVERE"]
    if errors:
        fail("%s: console errors: %s" % (path, errors))
    resources = driver.execute_script(
        "return performance.getEntriesByType('resource').map(e => e.name)")
    remote = [r for r in resources if not r.startswith("file:") and not r.startswith("data:")]
    if remote:
        fail("%s: network requests: %s" % (path, remote))
    verdict = driver.execute_script(
        "const v = document.getElementById('verdict'); return v ? "
        "{text: v.innerText, items: v.querySelectorAll('li').length, top: "
        "v.getBoundingClientRect().top} : null")
    if not verdict or not verdict["text"].strip() or verdict["items"] == 0:
        fail("%s: #verdict missing or empty: %s" % (path, verdict))
    first = driver.execute_script(
        "const s = document.querySelector('section, table, canvas'); return s ? s.id : null")
    if first != "verdict":
        fail("%s: the first section/table/plot is '%s', not the verdict" % (path, first))
    for tid in expect_tables:
        rows = driver.execute_script(
            "const t = document.getElementById(arguments[0]); "
            "return t ? t.querySelectorAll('tbody tr').length : -1", tid)
        if rows <= 0:
            fail("%s: table #%s missing or empty (%s rows)" % (path, tid, rows))
    canvases = driver.execute_script(CANVAS_STATE)
    if len(canvases) < min_plots:
        fail("%s: %d plots, expected at least %d" % (path, len(canvases), min_plots))
    for c in canvases:
        if not c["chart"] or c["points"] == 0 or c["ink"] < 300 or c["w"] < 100:
            fail("%s: plot %s not drawn or empty: %s" % (path, c["id"], c))
    print("%s: verdict with %d lines, %d plots drawn (%s)" % (
        os.path.basename(path), verdict["items"], len(canvases),
        ", ".join("%s %d px" % (c["id"], c["ink"]) for c in canvases)), flush=True)
    # Whole page in the screenshot.
    height = driver.execute_script("return document.documentElement.scrollHeight")
    driver.set_window_size(1400, min(max(1000, height + 100), 16000))
    driver.save_screenshot(screenshot)
    if not os.path.exists(screenshot) or os.path.getsize(screenshot) < 10000:
        fail("screenshot %s not written" % screenshot)
    driver.set_window_size(1400, 1000)
    return canvases


# The held-out residual vectors: one segment (2 points, then a gap) per held-out dot, the scale
# in the legend and the title, the image frame's y axis downwards, and the vectors' own pixels
# drawn in their colour (not only the outline and the axes).
VECTORS_STATE = """
const c = window.msmcalCharts['plot-validation-vectors'];
const d = c.data.datasets.find(s => s.label.startsWith('measured - predicted'));
const ctx = c.canvas.getContext('2d');
const img = ctx.getImageData(0, 0, c.canvas.width, c.canvas.height).data;
let red = 0;
for (let i = 0; i < img.length; i += 4) {
  if (img[i + 3] > 0 && img[i] > 150 && img[i + 1] < 90 && img[i + 2] < 90) red++;
}
return {label: d ? d.label : null, points: d ? d.data.filter(p => p.y !== null).length : 0,
        gaps: d ? d.data.filter(p => p.y === null).length : 0, red: red,
        title: c.options.plugins.title.text, reversed: c.options.scales.y.reverse};
"""


def check_vectors(driver, canvases):
    driver.execute_script("document.getElementById('plot-validation-vectors')"
                          ".scrollIntoView({block: 'center'})")
    v = driver.execute_script(VECTORS_STATE)
    import re
    scale = re.search(r"x(\d[\d.e+]*)", v["label"] or "")
    if not v["label"] or v["points"] < 2 or v["points"] != 2 * v["gaps"] or not scale:
        fail("held-out residual vectors: no segments or no scale in the legend: %s" % v)
    if ("x" + scale.group(1)) not in v["title"] or not v["reversed"]:
        fail("held-out residual vectors: title without the scale or y axis not downwards: %s" % v)
    if v["red"] < 20:
        fail("held-out residual vectors: the vectors are not drawn (%d red pixels): %s"
             % (v["red"], v))
    print("held-out residual vectors: %d segments, scale %s, %d vector pixels" % (
        v["gaps"], scale.group(1), v["red"]), flush=True)


def check_zoom(driver, chart_id):
    """Drag a rectangle on the chart: its axes narrow; double-click: they come back."""
    from selenium.webdriver.common.action_chains import ActionChains
    get = ("const c = window.msmcalCharts[arguments[0]]; "
           "return [c.scales.x.min, c.scales.x.max, c.scales.y.min, c.scales.y.max];")
    before = driver.execute_script(get, chart_id)
    canvas = driver.find_element("id", chart_id)
    driver.execute_script("arguments[0].scrollIntoView({block: 'center'})", canvas)
    w, h = canvas.size["width"], canvas.size["height"]
    # Offsets are from the element's centre.
    ActionChains(driver).move_to_element_with_offset(canvas, -w // 6, -h // 6).click_and_hold() \
        .move_by_offset(w // 8, h // 8).move_by_offset(w // 8, h // 8).release().perform()
    after = driver.execute_script(get, chart_id)
    if not (after[1] - after[0] < 0.8 * (before[1] - before[0])):
        fail("drag did not zoom %s: x range %s -> %s" % (chart_id, before[:2], after[:2]))
    ActionChains(driver).double_click(canvas).perform()
    reset = driver.execute_script(get, chart_id)
    if abs((reset[1] - reset[0]) - (before[1] - before[0])) > 1e-9 * abs(before[1] - before[0]):
        fail("double-click did not reset %s: %s -> %s" % (chart_id, before, reset))
    # Hover: the tooltip shows a value with the axis unit.
    ActionChains(driver).move_to_element(canvas).perform()
    print("zoom and reset on %s: x range %.4g -> %.4g -> %.4g" % (
        chart_id, before[1] - before[0], after[1] - after[0], reset[1] - reset[0]), flush=True)


def main():
    if len(sys.argv) != 3:
        fail("usage: report_browser_test.py MSMCAL_BINARY OUT_DIR")
    msmcal, out = sys.argv[1], os.path.abspath(sys.argv[2])
    driver = open_browser()  # skip early when the browser is missing
    try:
        shutil.rmtree(out, ignore_errors=True)
        os.makedirs(out)
        # Bad input: a folder that is neither a session nor a sweep is named in the error.
        empty = os.path.join(out, "empty")
        os.makedirs(empty)
        r = run([msmcal, "report", empty])
        if r.returncode == 0 or "neither a session folder" not in r.stdout or empty not in r.stdout:
            fail("msmcal report on an empty folder: exit %d\n%s" % (r.returncode, r.stdout))
        with open(os.path.join(out, "sim.yaml"), "w") as f:
            f.write(SIM)
        session = os.path.join(out, "demo")
        r = run([msmcal, "demo", "--out", session, "--config", os.path.join(out, "sim.yaml")])
        with open(os.path.join(out, "demo.log"), "w") as f:
            f.write(r.stdout)
        report = os.path.join(session, "report.html")
        if not os.path.exists(report):
            fail("msmcal demo wrote no report (exit %d):\n%s" % (r.returncode, r.stdout[-3000:]))
        if "== Verdict: " not in r.stdout:
            fail("the demo's printed report has no verdict:\n" + r.stdout[-2000:])
        with open(os.path.join(session, "results", "summary.json")) as f:
            prov = json.load(f)["provenance"]
        if "demo" not in prov["command_line"] or not prov["git_commit"]:
            fail("provenance of the demo: %s" % prov)
        if not any(role == "hall_mcu" and "sensor" in ident for role, ident in prov["instruments"]):
            fail("provenance has no Hall MCU identity: %s" % prov["instruments"])

        # `msmcal report` regenerates it, keeping the session's provenance.
        r = run([msmcal, "report", session, "--quiet"])
        if r.returncode != 0:
            fail("msmcal report %s: exit %d\n%s" % (session, r.returncode, r.stdout))
        with open(os.path.join(session, "results", "summary.json")) as f:
            prov2 = json.load(f)["provenance"]
        if prov2["command_line"] != prov["command_line"] or "report" not in prov2.get(
                "report_command_line", ""):
            fail("provenance after msmcal report: %s" % prov2)

        canvases = check_page(driver, report, os.path.join(out, "report.png"),
                              ["table-one", "table-two", "table-provenance"], min_plots=12)
        page = driver.page_source
        if prov["git_commit"] not in page:
            fail("the report does not show the commit %s" % prov["git_commit"])
        ids = {c["id"] for c in canvases}
        for needed in ("plot-scan-pattern", "plot-pose-alpha", "plot-normalised-errors",
                       "plot-hall-fit-alpha", "plot-delta-t-cost", "plot-clock-edges",
                       "plot-residual-families", "plot-whitened-histogram",
                       "plot-validation-vectors"):
            if needed not in ids:
                fail("plot %s missing (have %s)" % (needed, sorted(ids)))
        check_vectors(driver, canvases)
        check_zoom(driver, "plot-pose-alpha")

        # A sweep folder around the session: one point, the demo's folder.
        sweep = os.path.join(out, "sweep")
        os.makedirs(sweep)
        with open(os.path.join(sweep, "sweep.yaml"), "w") as f:
            f.write(PLAN)
        r = run([msmcal, "sweep", os.path.join(sweep, "sweep.yaml"), "--out", sweep, "--list"])
        names = [ln.split()[0] for ln in r.stdout.splitlines() if ln.startswith("  p")]
        if r.returncode != 0 or len(names) != 1:
            fail("msmcal sweep --list: %s" % r.stdout)
        shutil.copytree(session, os.path.join(sweep, names[0]), symlinks=True)
        r = run([msmcal, "report", sweep])
        if r.returncode != 0 or "sweep report:" not in r.stdout:
            fail("msmcal report %s: exit %d\n%s" % (sweep, r.returncode, r.stdout))
        # One plot per figure against the axis (normal, validation, Hall RMS, delta_t); a figure
        # no point has (the demo's tiny recording leaves delta_t not identified) is named in
        # #not-plotted instead of an empty plot.
        check_page(driver, os.path.join(sweep, "report.html"),
                   os.path.join(out, "sweep_report.png"), ["table-points"], min_plots=3)
        drawn = driver.execute_script("return document.querySelectorAll('canvas').length")
        note = driver.execute_script(
            "const n = document.getElementById('not-plotted'); return n ? n.textContent : ''")
        if drawn + note.count(" against ") != 4:
            fail("sweep report: %d plots and not plotted '%s': expected 4 figures in all" %
                 (drawn, note))
        link = driver.execute_script(
            "const a = document.querySelector('#table-points a'); return a ? a.href : null")
        if not link or not link.endswith(names[0] + "/report.html"):
            fail("the sweep report does not link the point's report: %s" % link)
        driver.get(link)
        wait_for(driver, "return document.getElementById('verdict') !== null", "point report")
        print("PASS: screenshots %s, %s" % (os.path.join(out, "report.png"),
                                          os.path.join(out, "sweep_report.png")), flush=True)
    finally:
        driver.quit()


if __name__ == "__main__":
    main()
