"""Benchmark of the phone page: its weight and how soon it paints, in Debian's chromium on loopback.

    .venv/bin/python bench/bench_page.py [--loads 10]

Starts ``flask-move-server --sim`` (its own ROS master) and opens the page ``--loads`` times, each
in a fresh browser context (nothing cached), at phone size (390×844, touch). For each load: first
contentful paint (the browser's own paint timing), the moment the page is connected (live or
polling), the moment the robot is drawn and the moment the map image is. The weight is every byte the page's files
take (what the server sends for them, the map image aside). Targets (issue 13): <= 150 KB, first
paint <= 1 s. Needs Playwright (the ``test`` extra) and /usr/bin/chromium.

Prints a markdown table (docs/performance.md, section Phone page).
"""

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import threading
import time

import requests

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from tests.page_browser import CHROMIUM, CHROMIUM_ARGS, PHONE  # noqa: E402

STATIC = os.path.join(ROOT, "flask_move_server", "web", "static")
TIMING = """() => new Promise((resolve) => {
  setTimeout(() => resolve({paint: null}), 3000);
  new PerformanceObserver((list) => {
    const paint = list.getEntries().find((e) => e.name === 'first-contentful-paint');
    if (paint) resolve({paint: paint.startTime});
  }).observe({type: 'paint', buffered: true});
})"""


def wait_for(predicate, timeout, message):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            value = predicate()
        except requests.RequestException:
            value = None
        if value:
            return value
        time.sleep(0.05)
    raise SystemExit("timed out waiting for " + message)


def files_on_disk():
    """(bytes, files) of everything under static/ as stored."""
    sizes = [os.path.getsize(os.path.join(d, f)) for d, _, names in os.walk(STATIC) for f in names]
    return sum(sizes), len(sizes)


def start_server(tmp):
    env = dict(os.environ, ROS_MASTER_URI="http://127.0.0.1:{}".format(_free_port()), ROS_HOME=tmp,
               ROS_LOG_DIR=os.path.join(tmp, "log"), ROS_IP="127.0.0.1", PYTHONUNBUFFERED="1")
    waypoints = os.path.join(tmp, "waypoints.yaml")
    with open(os.path.join(ROOT, "config", "waypoints.demo.yaml")) as src, open(waypoints, "w") as dst:
        dst.write(src.read())
    server = subprocess.Popen([sys.executable, "-m", "flask_move_server", "--sim", "--port", "0", "--no-mdns",
                               "--waypoints", waypoints], env=env, cwd=ROOT, stderr=subprocess.PIPE, text=True)
    lines = []
    threading.Thread(target=lambda: lines.extend(server.stderr), daemon=True).start()
    match = wait_for(lambda: next((re.search(r"serving the API on (http://\S+)", x) for x in list(lines)
                                   if "serving the API" in x), None), 60, "the server")
    url = match.group(1)
    wait_for(lambda: requests.get(url + "/status", timeout=2).json()["pose"], 30, "a pose")
    return server, url


def _free_port():
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def load(browser, url):
    """One cold load: (first paint ms, connected ms, robot drawn ms, bytes, files)."""
    context = browser.new_context(**PHONE)
    page = context.new_page()
    responses = []
    page.on("response", lambda r: responses.append(r))
    started = time.monotonic()
    page.goto(url + "/")
    page.wait_for_function("['live', 'polling'].includes(document.body.dataset.connection)")
    connected = (time.monotonic() - started) * 1000
    page.wait_for_function("document.getElementById('map').dataset.robotPx")
    drawn = (time.monotonic() - started) * 1000
    page.wait_for_function("document.getElementById('map').dataset.imageRect")
    mapped = (time.monotonic() - started) * 1000
    timing = page.evaluate(TIMING)
    files = [r for r in responses if r.url.rstrip("/") == url or "/static/" in r.url]
    size = sum(len(r.body()) for r in files)
    image = len(requests.get(url + "/map/image", timeout=10).content)
    context.close()
    return timing["paint"], connected, drawn, size, len(files), mapped, image


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--loads", type=int, default=10)
    args = parser.parse_args()
    from playwright.sync_api import sync_playwright

    with tempfile.TemporaryDirectory() as tmp:
        server, url = start_server(tmp)
        try:
            with sync_playwright() as pw:
                browser = pw.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS, headless=True)
                runs = [load(browser, url) for _ in range(args.loads)]
                browser.close()
        finally:
            server.terminate()
            server.wait(10)
    report(runs)
    return 0


def report(runs):
    stored, stored_files = files_on_disk()
    paints, connected, drawn, mapped = ([r[i] for r in runs if r[i] is not None] for i in (0, 1, 2, 5))
    print("\n## The phone page ({} cold loads, 390×844, Debian's chromium, loopback)\n".format(len(runs)))
    print("| measure | median | max |")
    print("|---|---:|---:|")
    for name, values in (("first contentful paint", paints), ("connected (live or polling)", connected),
                         ("robot drawn", drawn), ("map image drawn", mapped)):
        print("| {} | {:.0f} ms | {:.0f} ms |".format(name, statistics.median(values), max(values)))
    print("\n| weight | value |")
    print("|---|---:|")
    print("| the page's files as sent (the map image aside) | {:.1f} KB in {} files |".format(runs[0][3] / 1024,
                                                                                          runs[0][4]))
    print("| static/ on disk | {:.1f} KB in {} files |".format(stored / 1024, stored_files))
    print("| the map image (`/map/image`, the demo flat) | {:.1f} KB |".format(runs[0][6] / 1024))


if __name__ == "__main__":
    sys.exit(main())
