"""Benchmark: from a Wi-Fi that goes silent to the phone page saying so, and a goal sent in between.

    .venv/bin/python bench/bench_page_silence.py [--stalls 5]

Starts ``flask-move-server --sim`` (its own ROS master) and opens the page at phone size in
Debian's chromium. Each round freezes the server with SIGSTOP (its sockets stay open: nothing
closes, nothing arrives, as a phone on a Wi-Fi that stops passing packets sees it), at a random
moment of the robot's 2 s clock cycle, and measures:

- silence → "reconnecting": the time until the page's chip leaves `live`;
- a goal dragged 0.5 s into the stall: when its "did not answer" appears on the page, and after the
  server is thawed 5 s into the stall, whether the robot drove it (it must not: it arrives late).

Prints a markdown table (docs/performance.md, section "The page on a stalling Wi-Fi").
"""

import argparse
import os
import random
import signal
import statistics
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from tests.page_browser import Browser, Finger, PageSim, live  # noqa: E402
from tests.test_page import Screen, on_page  # noqa: E402

GOAL = (1.0, 1.0)


def one_stall(sim, page, rng):
    page.wait_for_timeout(rng.uniform(0, 2000))  # anywhere in the clock's 2 s cycle
    sim.post("/stop")
    start = Screen(page, sim).screen(*GOAL)
    os.kill(sim.proc.pid, signal.SIGSTOP)
    stalled = time.monotonic()
    try:
        page.wait_for_timeout(500)
        finger = Finger(page, on_page(page, start))
        finger.move(on_page(page, (start[0] + 40, start[1])))
        finger.lift()
        sent = time.monotonic()
        page.wait_for_function("document.body.dataset.connection === 'reconnecting'", timeout=60000)
        noticed = time.monotonic() - stalled
        told = said_in_time(page, "did not answer", 10000, sent)
        page.wait_for_timeout(max(0, 5000 - (time.monotonic() - stalled) * 1000))
    finally:
        os.kill(sim.proc.pid, signal.SIGCONT)
    live(page, timeout=30000)
    page.wait_for_timeout(500)
    nav = sim.status()["navigation"]
    goal = nav.get("goal")
    driven = nav["state"] == "active" and goal is not None and abs(goal["x"] - GOAL[0]) < 0.3
    return noticed, told, driven


def said_in_time(page, words, timeout_ms, since):
    """Seconds from ``since`` until the error line holds ``words``; None when it never did."""
    try:
        page.wait_for_function("(w) => document.getElementById('error').textContent.includes(w)", arg=words,
                               timeout=timeout_ms)
    except Exception:  # the page as it was before issue 22 said nothing at all
        return None
    return time.monotonic() - since


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stalls", type=int, default=5)
    args = parser.parse_args()
    rng = random.Random(7)
    sim = PageSim(__import__("pathlib").Path(tempfile.mkdtemp(prefix="bench-silence-")))
    browser = Browser()
    try:
        page = browser.open(sim.url + "/")
        live(page)
        clock_known = "document.body.dataset.robotClock === 'known' || !document.querySelector('#stop .outcome')"
        page.wait_for_function(clock_known, timeout=10000)  # (a page from before issue 22 has no clock)
        page.wait_for_function("document.getElementById('map').dataset.imageRect", timeout=30000)
        rounds = [one_stall(sim, page, rng) for _ in range(args.stalls)]
    finally:
        browser.close()
        sim.close()
    noticed = [r[0] for r in rounds]
    told = [r[1] for r in rounds if r[1] is not None]
    print("| stalls | silence → not live, median (min–max) | goal sent → \"did not answer\", median "
          "| late goals driven |")
    print("|---:|---|---:|---:|")
    print("| {} | {:.1f} s ({:.1f}–{:.1f}) | {} | {} |".format(
        len(rounds), statistics.median(noticed), min(noticed), max(noticed),
        "{:.1f} s".format(statistics.median(told)) if told else "never",
        sum(r[2] for r in rounds)))


if __name__ == "__main__":
    main()
