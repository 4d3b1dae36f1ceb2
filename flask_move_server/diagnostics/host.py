"""The Pi itself, for the first-boot doctor: power, heat, load, disk and clock.

Each reading comes from a file or command a Raspberry Pi OS or Ubuntu Pi has (``root`` lets
tests point the ``/sys`` and ``/run`` reads at a folder of their own); each check is pure over
its reading. A reading a machine does not have (not a Pi, no systemd) is a ``skip``, not a
failure: the sim on a laptop has no undervoltage bit.
"""

import os
import shutil
import subprocess
import time
from dataclasses import dataclass
from typing import Optional

from flask_move_server.diagnostics.checks import FAIL, PASS, SKIP, WARN, Check

THROTTLED_FILE = "sys/devices/platform/soc/soc:firmware/get_throttled"
THERMAL_FILE = "sys/class/thermal/thermal_zone0/temp"
TIMESYNC_FILE = "run/systemd/timesync/synchronized"
CLOCK_FLOOR = 1735689600  # 2025-01-01 UTC: a Pi without network (no RTC) boots earlier than any release of ours
# get_throttled's bits (the Raspberry Pi firmware's documentation of vcgencmd)
UNDERVOLTAGE_NOW, CAPPED_NOW, THROTTLED_NOW, SOFT_TEMP_NOW = 0x1, 0x2, 0x4, 0x8
UNDERVOLTAGE_SINCE_BOOT, THROTTLED_SINCE_BOOT = 0x10000, 0x40000


@dataclass
class HostReadings:
    """What the doctor read of the machine it runs on."""

    throttled: Optional[int]
    temperature: Optional[float]   # °C
    load: float                    # 1-minute load average per core
    free_bytes: Optional[int]      # on the maps folder's file system
    clock: float                   # time.time()
    clock_synced: Optional[bool]   # NTP synchronised, when the system says


def read(maps_folder, root="/"):
    """Read everything the host checks need (cheap: a few small files, at most one short command)."""
    return HostReadings(throttled=_throttled(root), temperature=_temperature(root),
                        load=os.getloadavg()[0] / (os.cpu_count() or 1), free_bytes=_free(maps_folder),
                        clock=time.time(), clock_synced=_clock_synced(root))


def _read_text(root, name):
    try:
        with open(os.path.join(root, name), encoding="ascii") as f:
            return f.read().strip()
    except (OSError, ValueError):
        return None


def _throttled(root):
    text = _read_text(root, THROTTLED_FILE)
    if text is None and root == "/" and shutil.which("vcgencmd"):
        text = _command(["vcgencmd", "get_throttled"]).partition("=")[2]
    try:
        return int(text, 16) if text else None
    except ValueError:
        return None


def _temperature(root):
    text = _read_text(root, THERMAL_FILE)
    try:
        return int(text) / 1000.0 if text else None
    except ValueError:
        return None


def _free(folder):
    path = folder
    while path and not os.path.exists(path):
        path = os.path.dirname(path)
    try:
        return shutil.disk_usage(path or "/").free
    except OSError:
        return None


def _clock_synced(root):
    if os.path.exists(os.path.join(root, TIMESYNC_FILE)):
        return True
    if root != "/" or not shutil.which("timedatectl"):
        return None
    answer = _command(["timedatectl", "show", "-p", "NTPSynchronized", "--value"])
    return {"yes": True, "no": False}.get(answer)


def _command(argv):
    try:
        return subprocess.run(argv, capture_output=True, text=True, timeout=2).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ""


def host_checks(readings):
    """Power, heat, load, disk, clock."""
    return [power_check(readings.throttled), temperature_check(readings.temperature), load_check(readings.load),
            disk_check(readings.free_bytes), clock_check(readings.clock, readings.clock_synced)]


def power_check(throttled):
    if throttled is None:
        return Check("power", SKIP, "not a Raspberry Pi (no get_throttled)")
    supply = "Use the official 5.1 V 3 A supply (5 A for a Pi 5) and a short thick cable; never feed the Pi " \
             "from the motor battery's regulator without a capacitor."
    if throttled & UNDERVOLTAGE_NOW:
        return Check("power", FAIL, "under-voltage now (get_throttled 0x{:x})".format(throttled), supply)
    if throttled & (CAPPED_NOW | THROTTLED_NOW | SOFT_TEMP_NOW):
        return Check("power", WARN, "the CPU is throttled now (get_throttled 0x{:x})".format(throttled),
                     "Too hot or too little power: see the temperature line; add a heatsink or fan.")
    if throttled & (UNDERVOLTAGE_SINCE_BOOT | THROTTLED_SINCE_BOOT):
        return Check("power", WARN, "under-voltage or throttling since boot (get_throttled 0x{:x})".format(throttled),
                     "It happens when the motors start: " + supply)
    return Check("power", PASS, "no under-voltage or throttling since boot")


def temperature_check(celsius):
    if celsius is None:
        return Check("temperature", SKIP, "no CPU temperature sensor")
    text = "CPU at {:.0f} °C".format(celsius)
    if celsius >= 80:
        return Check("temperature", FAIL, text + ": the Pi slows itself down", "Add a heatsink or a fan.")
    if celsius >= 70:
        return Check("temperature", WARN, text, "A heatsink keeps gmapping and DWA at full speed.")
    return Check("temperature", PASS, text)


def load_check(load_per_core):
    text = "load {:.2f} per core".format(load_per_core)
    if load_per_core > 1.5:
        return Check("load", WARN, text + ": the Pi is overloaded", "Something else is running, or the "
                     "navigation stack asks too much (docs/performance.md); top shows who.")
    return Check("load", PASS, text)


def disk_check(free_bytes):
    if free_bytes is None:
        return Check("disk", SKIP, "the maps folder's disk could not be read")
    text = "{:.0f} MB free for maps".format(free_bytes / 1e6)
    if free_bytes < 50e6:
        return Check("disk", FAIL, text + ": saving a map may fail", "Free space: sudo journalctl --vacuum-size=100M; "
                     "rm -r ~robot/.ros/log; delete old maps (robotctl map rm NAME).")
    if free_bytes < 500e6:
        return Check("disk", WARN, text, "ROS logs grow: sudo journalctl --vacuum-size=100M; rm -r ~robot/.ros/log.")
    return Check("disk", PASS, text)


def clock_check(now, synced):
    when = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime(now))
    if now < CLOCK_FLOOR:
        return Check("clock", FAIL, "the clock says {}: it was never set".format(when),
                     "A Pi has no battery clock: connect it to a network with internet (NTP), or set it: "
                     "sudo date -s '2026-01-31 12:00'. Schedules, logs and ROS stamps need it.")
    if synced is False:
        return Check("clock", WARN, "the clock ({}) is not synchronised (NTP)".format(when),
                     "sudo timedatectl set-ntp true, and a network with internet.")
    return Check("clock", PASS, "the clock says {}{}".format(when, "" if synced else " (sync state unknown)"))
