"""The mDNS records and wire format, without a network: pure functions."""

import os
import socket
import subprocess
import sys

import pytest
from zeroconf import DNSAddress, DNSIncoming, DNSOutgoing, DNSService

from flask_move_server import API_VERSION, __version__, config
from flask_move_server.core.errors import ConfigError
from flask_move_server.lan import discovery, dns_wire, mdns
from flask_move_server.lan import records as mdns_records

INTERFACES = [
    ("lo", "127.0.0.1"), ("lo", "::1"), ("eth0", "192.168.1.20"), ("eth0", "fe80::1%2"),
    ("wlan0", "10.0.0.5"), ("wlan0", "2001:db8::5"), ("docker0", "not-an-address"),
]


def _answers(incoming):
    return incoming.answers() if callable(incoming.answers) else incoming.answers


def test_both_service_types_are_advertised_under_one_instance_with_the_api_in_txt():
    records = mdns_records.service_records("kitchen bot", "robot", 5000, ["192.168.1.20"], token_required=True)
    assert [r.type for r in records] == ["_flask-move._tcp.local.", "_http._tcp.local."]
    assert [r.name for r in records] == ["kitchen bot._flask-move._tcp.local.", "kitchen bot._http._tcp.local."]
    for record in records:
        assert record.server == "robot.local."
        assert record.port == 5000
        assert record.addresses == ("192.168.1.20",)
        assert record.properties == {"path": "/", "api": API_VERSION, "token": "yes", "version": __version__}


def test_without_a_token_txt_says_so_and_a_local_suffix_is_not_doubled():
    (record, _) = mdns_records.service_records("robot", "robot.local.", 8080, [], token_required=False)
    assert record.properties["token"] == "no"
    assert record.server == "robot.local."
    assert record.addresses == ()


def test_records_become_zeroconf_service_infos_that_a_client_reads_back_as_a_robot():
    (record, _) = mdns_records.service_records("robot", "robot", 5000, ["192.168.1.20", "10.0.0.5"], True)
    info = mdns._service_info(record)
    robot = discovery.robot_from_service(record.type, record.name, info)
    assert robot == discovery.FoundRobot("robot", "robot.local", ("192.168.1.20", "10.0.0.5"), 5000, True,
                                    __version__, API_VERSION)
    assert robot.url == "http://robot.local:5000"


@pytest.mark.parametrize("bind_host, expected", [
    ("0.0.0.0", ("10.0.0.5", "192.168.1.20")),
    ("::", ("10.0.0.5", "192.168.1.20", "2001:db8::5")),
    ("192.168.1.20", ("192.168.1.20",)),
    ("192.168.1.99", ()),
    ("127.0.0.1", ()),
])
def test_only_addresses_the_server_is_reachable_on_are_advertised(bind_host, expected):
    assert mdns_records.reachable_addresses(bind_host, INTERFACES) == expected


def test_avahi_counts_as_running_only_when_its_pid_file_names_a_live_process(tmp_path):
    pid_file = tmp_path / "pid"
    assert not mdns.avahi_running(str(pid_file))
    pid_file.write_text("garbage\n")
    assert not mdns.avahi_running(str(pid_file))
    pid_file.write_text("{}\n".format(os.getpid()))
    assert mdns.avahi_running(str(pid_file))
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()
    pid_file.write_text("{}\n".format(gone.pid))
    assert not mdns.avahi_running(str(pid_file))


def test_conflicts_name_other_devices_on_our_host_name_and_a_taken_instance():
    records = [
        ("robot.local.", dns_wire.TYPE_A, socket.inet_aton("192.168.1.7")),
        ("robot.local.", dns_wire.TYPE_A, socket.inet_aton("192.168.1.20")),
        ("Robot._http._tcp.local.", dns_wire.TYPE_SRV, b"\0" * 8),
    ]
    assert mdns_records.conflicts(records, "robot", "robot", ("192.168.1.20",)) == (["192.168.1.7"], True)
    assert mdns_records.conflicts(records, "robot", "office", ("192.168.1.7", "192.168.1.20")) == ([], False)
    assert mdns_records.conflicts([], "robot", "robot", ()) == ([], False)


def test_conflict_questions_skip_the_host_name_when_avahi_owns_it():
    assert mdns_records.conflict_questions(None, "robot") == [
        ("robot._flask-move._tcp.local.", dns_wire.TYPE_SRV), ("robot._http._tcp.local.", dns_wire.TYPE_SRV)]
    assert ("robot.local.", dns_wire.TYPE_A) in mdns_records.conflict_questions("robot", "robot")


def test_the_query_packet_is_what_zeroconf_itself_parses():
    packet = dns_wire.build_query([("robot.local.", dns_wire.TYPE_A), ("robot.local.", dns_wire.TYPE_AAAA)], 77)
    incoming = DNSIncoming(packet)
    assert incoming.id == 77 and incoming.is_query()
    assert [(q.name, q.type) for q in incoming.questions] == [("robot.local.", 1), ("robot.local.", 28)]


def _response(records, id_=77):
    out = DNSOutgoing(0x8400, multicast=False, id_=id_)
    for record in records:
        out.add_answer_at_time(record, 0)
    return out.packets()[0]


def test_addresses_are_read_from_a_zeroconf_response_with_compressed_names():
    packet = _response([
        DNSService("robot._http._tcp.local.", 33, 1, 120, 0, 0, 5000, "robot.local."),
        DNSAddress("robot.local.", 1, 1, 120, socket.inet_aton("10.1.2.3")),
        DNSAddress("ROBOT.local.", 28, 1, 120, socket.inet_pton(socket.AF_INET6, "2001:db8::7")),
        DNSAddress("other.local.", 1, 1, 120, socket.inet_aton("10.9.9.9")),
    ])
    assert dns_wire.parse_addresses(packet, "robot.local.", 77) == ["10.1.2.3", "2001:db8::7"]
    assert dns_wire.parse_addresses(packet, "robot.local.", 78) == []
    assert dns_wire.parse_addresses(packet[:40], "robot.local.", 77) == []


def test_a_query_is_not_taken_for_an_answer():
    assert dns_wire.parse_addresses(dns_wire.build_query([("robot.local.", 1)], 5), "robot.local.") == []


@pytest.mark.parametrize("name, expected", [
    ("robot.local", "robot.local."), ("Robot.Local.", "robot.local."), ("robot", None), ("example.com", None),
    (".local", None),
])
def test_only_local_names_are_resolved_over_mdns(name, expected):
    assert dns_wire.local_name(name) == expected


def test_resolving_a_non_local_name_returns_none_without_asking():
    assert discovery.resolve_local("example.com", timeout=0.1) is None


@pytest.mark.parametrize("section, key, message", [
    ({"hostname": "robot.local"}, "mdns.hostname", "without .local ('robot', not 'robot.local')"),
    ({"hostname": "my robot"}, "mdns.hostname", "letters, digits or '-'"),
    ({"hostname": "-robot"}, "mdns.hostname", "not at either end"),
    ({"instance": "robot.one"}, "mdns.instance", "must not contain '.'"),
    ({"instance": "x" * 64}, "mdns.instance", "1 to 63 bytes"),
    ({"publish_hostname": "sometimes"}, "mdns.publish_hostname", "auto, always, never"),
    ({"address_check_period": 0}, "mdns.address_check_period", "greater than 0"),
])
def test_bad_mdns_settings_are_refused_with_key_and_reason(section, key, message):
    with pytest.raises(ConfigError) as err:
        config.build(config.Config, {"mdns": section}, source="robot.yaml")
    assert err.value.key == key and message in err.value.reason


def test_the_advertiser_closes_safely_twice_even_unstarted():
    advertiser = mdns.Advertiser(config.MdnsConfig(), "0.0.0.0", 5000, False)
    advertiser.close()
    advertiser.close()
    assert advertiser.start().published is None


def test_with_avahi_running_the_host_name_is_left_to_avahi(tmp_path):
    pid_file = tmp_path / "pid"
    pid_file.write_text("{}\n".format(os.getpid()))
    system = socket.gethostname().split(".")[0]
    for settings, pid_path, expected in [
        (config.MdnsConfig(), pid_file, (system, system, False)),
        (config.MdnsConfig(instance="Kitchen bot"), pid_file, (system, "Kitchen bot", False)),
        (config.MdnsConfig(publish_hostname="never"), tmp_path / "none", (system, system, False)),
        (config.MdnsConfig(publish_hostname="always"), pid_file, ("robot", "robot", True)),
        (config.MdnsConfig(), tmp_path / "none", ("robot", "robot", True)),
    ]:
        advertiser = mdns.Advertiser(settings, "0.0.0.0", 5000, False, avahi_pid_file=str(pid_path))
        advertiser._stop.set()  # decide the names without asking the network about conflicts
        assert advertiser._names(("10.0.0.5",)) == expected
