"""tests/netns.py's probe: where namespaces only half work, the LAN tests skip saying why."""

import os
import stat

import pytest

from tests import netns

# An `ip` that creates and deletes namespaces but fails at one later step, as in some containers.
FAKE_IP = """#!/bin/sh
case "$*" in
  "netns add "*|"netns del "*) exit 0 ;;
  "-n "*) [ "$FAIL" = "-n" ] && { echo "mount of /sys failed: Operation not permitted" >&2; exit 1; } ;;
  "netns exec "*) [ "$FAIL" = "exec" ] && { echo "setting the netns failed: Invalid argument" >&2; exit 255; } ;;
esac
exit 0
"""


@pytest.fixture
def fake_ip(tmp_path, monkeypatch):
    path = tmp_path / "ip"
    path.write_text(FAKE_IP)
    path.chmod(path.stat().st_mode | stat.S_IXUSR)
    monkeypatch.setenv("PATH", "{}{}{}".format(tmp_path, os.pathsep, os.environ["PATH"]))
    return monkeypatch


def test_a_namespace_ip_cannot_configure_is_a_skip_reason_with_ips_words(fake_ip):
    fake_ip.setenv("FAIL", "-n")
    reason = netns.unavailable_reason()
    assert reason.startswith("`ip -n` failed (mount of /sys failed: Operation not permitted)")


def test_a_namespace_nothing_can_run_in_is_a_skip_reason_with_ips_words(fake_ip):
    fake_ip.setenv("FAIL", "exec")
    reason = netns.unavailable_reason()
    assert reason.startswith("`ip netns exec` failed (setting the netns failed: Invalid argument)")


def test_working_namespaces_are_no_reason_to_skip(fake_ip):
    fake_ip.setenv("FAIL", "")
    assert netns.unavailable_reason() is None
