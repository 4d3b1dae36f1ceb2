"""Configuration: defaults, the documented example, validation that names file, key and reason."""

import os
import socket

import pytest

from flask_move_server import config
from flask_move_server.app import server_options
from flask_move_server.config import access
from flask_move_server.core.errors import ConfigError
from flask_move_server.drive import backends
from tests.conftest import ROOT, run_cli

EXAMPLE = os.path.join(ROOT, "config", "robot.yaml")


def _write(tmp_path, text):
    path = tmp_path / "robot.yaml"
    path.write_text(text)
    return str(path)


def _without_paths(data):
    data = config.as_plain(data)
    data["waypoints"].pop("file")
    return data


def test_the_documented_example_is_exactly_the_defaults():
    assert _without_paths(config.load(EXAMPLE)) == _without_paths(config.Config())


def test_every_default_key_is_documented_in_the_example():
    import yaml

    with open(EXAMPLE) as f:
        documented = yaml.safe_load(f)

    def keys(data, prefix=""):
        for k, v in data.items():
            yield prefix + k
            if isinstance(v, dict):
                yield from keys(v, prefix + k + ".")

    assert set(keys(config.as_plain(config.Config()))) == set(keys(documented))


def test_no_file_and_an_empty_file_give_the_defaults(tmp_path):
    assert config.load(None) == config.Config()
    loaded = config.load(_write(tmp_path, ""))
    assert loaded.server == config.ServerConfig() and loaded.teleop == config.TeleopConfig()


def test_relative_paths_are_relative_to_the_config_file(tmp_path):
    loaded = config.load(_write(tmp_path, "waypoints:\n  file: places.yaml\n"))
    assert loaded.waypoints.file == str(tmp_path / "places.yaml")


@pytest.mark.parametrize("text,key,reason", [
    ("server:\n  prot: 5000\n", "server.prot", "did you mean 'port'"),
    ("sever:\n  port: 5000\n", "sever", "did you mean 'server'"),
    ("server:\n  port: '5000'\n", "server.port", "whole number"),
    ("server:\n  port: 70000\n", "server.port", "TCP port"),
    ("teleop:\n  deadman: -1\n", "teleop.deadman", "greater than 0"),
    ("teleop:\n  max_linear: .nan\n", "teleop.max_linear", "finite number"),
    ("navigation:\n  goal_interface: actionlib\n", "navigation.goal_interface", "one of action, topic"),
    ("mdns:\n  enabled: 'yes please'\n", "mdns.enabled", "true or false"),
    ("ros:\n  frames: [map]\n", "ros.frames", "must be a mapping"),
    ("drive:\n  backend: pigpio\n", "drive.backend", "must be one of"),
])
def test_bad_values_name_the_file_the_key_and_the_reason(tmp_path, text, key, reason):
    path = _write(tmp_path, text)
    with pytest.raises(ConfigError) as err:
        config.load(path)
    assert err.value.key == key
    assert reason in err.value.reason
    assert str(err.value).startswith(path)


@pytest.mark.parametrize("text,reason", [
    ("server: [1, 2\n", "not valid YAML"),
    ("- just\n- a list\n", "top level must be a mapping"),
])
def test_a_file_that_is_not_a_config_says_so(tmp_path, text, reason):
    with pytest.raises(ConfigError, match=reason):
        config.load(_write(tmp_path, text))


def test_token_comes_from_the_env_var_first(tmp_path, monkeypatch):
    token_file = tmp_path / "token"
    token_file.write_text("from-file\n")
    loaded = config.load(_write(tmp_path, "server:\n  token_file: token\n"))
    monkeypatch.delenv(access.TOKEN_ENV, raising=False)
    assert loaded.resolved_token() == "from-file"
    monkeypatch.setenv(access.TOKEN_ENV, "from-env")
    assert loaded.resolved_token() == "from-env"


def test_serving_the_network_without_a_token_is_refused_with_the_fix(monkeypatch):
    monkeypatch.delenv(access.TOKEN_ENV, raising=False)
    cfg = config.Config()
    with pytest.raises(ConfigError) as err:
        access.check_serving_policy(cfg)
    assert access.TOKEN_ENV in str(err.value) and "--insecure" in str(err.value)
    cfg.server.insecure = True
    access.check_serving_policy(cfg)
    loopback = config.Config()
    loopback.server.host = "127.0.0.1"
    access.check_serving_policy(loopback)


def test_flags_override_the_file(tmp_path):
    path = _write(tmp_path, "server:\n  port: 6000\n  host: 127.0.0.1\n")
    args = server_options.parse_args(["--config", path, "--port", "7000", "--no-mdns", "--waypoints", "x.yaml"])
    loaded = server_options.load_config(args, [])
    assert loaded.server.port == 7000
    assert loaded.mdns.enabled is False
    assert loaded.waypoints.file == os.path.abspath("x.yaml")


def test_the_server_exits_2_on_a_bad_config_naming_file_key_and_reason(tmp_path):
    path = _write(tmp_path, "teleop:\n  max_linaer: 1.0\n")
    proc = run_cli("--config", path)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 2
    assert path in err and "teleop.max_linaer" in err and "did you mean 'max_linear'" in err
    assert "Traceback" not in err


def test_the_server_refuses_the_network_without_a_token():
    proc = run_cli("--host", "0.0.0.0", "--port", "0", env={access.TOKEN_ENV: ""})
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 2
    assert "refusing to serve 0.0.0.0 without a token" in err and "--insecure" in err


def test_a_taken_port_is_named_with_what_to_do(tmp_path):
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen(1)
        port = taken.getsockname()[1]
        proc = run_cli("--host", "127.0.0.1", "--port", str(port), "--no-mdns",
                       "--waypoints", str(tmp_path / "waypoints.yaml"), env={"ROS_MASTER_URI": "http://127.0.0.1:9"})
        _, err = proc.communicate(timeout=30)
    assert proc.returncode == 1
    assert "cannot listen on 127.0.0.1:{}: the port is in use".format(port) in err and "--port" in err
    assert "Traceback" not in err


def test_sim_serves_this_machine_only_even_with_a_config_file(tmp_path):
    path = _write(tmp_path, "server:\n  port: 6000\n")
    loaded = server_options.load_config(server_options.parse_args(["--config", path, "--sim"]), [])
    assert loaded.server.host == "127.0.0.1" and loaded.drive.backend == "sim"
    flags = ["--config", path, "--sim", "--host", "0.0.0.0", "--insecure"]
    loaded = server_options.load_config(server_options.parse_args(flags), [])
    assert loaded.server.host == "0.0.0.0"


# -- the token: one rule for every source --------------------------------------------------------


def _token_sources(tmp_path, text):
    """A config per source, each holding ``text`` as its token."""
    token_file = tmp_path / "token"
    token_file.write_text(text)
    token_file.chmod(0o600)
    in_file = config.load(_write(tmp_path, "server:\n  token_file: token\n"))
    in_config = config.Config()
    in_config.server.token = text
    return {"server.token_file": in_file, "server.token": in_config, access.TOKEN_ENV: config.Config()}


@pytest.mark.parametrize("key", ["server.token_file", "server.token", access.TOKEN_ENV])
def test_every_token_source_strips_whitespace_the_same_way(tmp_path, monkeypatch, key):
    monkeypatch.delenv(access.TOKEN_ENV, raising=False)
    cfg = _token_sources(tmp_path, "  s3cret \t\n")[key]
    if key == access.TOKEN_ENV:
        monkeypatch.setenv(access.TOKEN_ENV, "  s3cret \t\n")
    assert cfg.resolved_token() == "s3cret"


@pytest.mark.parametrize("key", ["server.token_file", "server.token"])
def test_a_token_that_is_only_whitespace_is_a_config_error(tmp_path, monkeypatch, key):
    monkeypatch.delenv(access.TOKEN_ENV, raising=False)
    cfg = _token_sources(tmp_path, " \n")[key]
    with pytest.raises(ConfigError) as err:
        access.check_serving_policy(cfg)
    assert err.value.key == key and "empty" in err.value.reason


@pytest.mark.parametrize("key", ["server.token_file", "server.token", access.TOKEN_ENV])
def test_a_non_ascii_token_is_refused_without_showing_it(tmp_path, monkeypatch, key):
    monkeypatch.delenv(access.TOKEN_ENV, raising=False)
    cfg = _token_sources(tmp_path, "grüße-ü-token")[key]
    if key == access.TOKEN_ENV:
        monkeypatch.setenv(access.TOKEN_ENV, "grüße-ü-token")
    cfg.server.host = "127.0.0.1"  # refused at start-up even when serving this machine only
    with pytest.raises(ConfigError) as err:
        access.check_serving_policy(cfg)
    assert err.value.key == key and "not printable ASCII (at position 3)" in err.value.reason
    assert "grüße" not in str(err.value) and "secrets.token_urlsafe" in str(err.value)


def test_the_server_refuses_a_non_ascii_token_at_start_up():
    proc = run_cli("--host", "127.0.0.1", "--port", "0", env={access.TOKEN_ENV: "grüße-ü-token"})
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 2
    assert "FLASK_MOVE_SERVER_TOKEN: the token has a character that is not printable ASCII" in err
    assert "grüße" not in err and "Traceback" not in err


def test_a_token_file_others_can_read_is_warned_about(tmp_path, monkeypatch, caplog):
    monkeypatch.delenv(access.TOKEN_ENV, raising=False)
    cfg = _token_sources(tmp_path, "s3cret\n")["server.token_file"]
    token_file = tmp_path / "token"
    with caplog.at_level("WARNING", logger="flask_move_server"):
        access.check_serving_policy(cfg)
    assert not caplog.records
    token_file.chmod(0o644)
    with caplog.at_level("WARNING", logger="flask_move_server"):
        access.check_serving_policy(cfg)
    (record,) = caplog.records
    assert str(token_file) in record.getMessage() and "chmod 600" in record.getMessage()
    assert "0644" in record.getMessage()


def test_every_registered_motor_backend_is_a_valid_drive_backend_and_no_other(tmp_path):
    for name in backends.names():
        assert config.load(_write(tmp_path, "drive:\n  backend: {}\n".format(name))).drive.backend == name
    with pytest.raises(ConfigError) as err:
        config.load(_write(tmp_path, "drive:\n  backend: pigpio\n"))
    assert ", ".join(backends.names()) in str(err.value)
