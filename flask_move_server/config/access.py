"""Who may use the server: the bearer token in force and the policy for serving without one.

The token comes from the environment, then ``server.token``, then ``server.token_file``; every
source is stripped and checked the same way. At start-up :func:`check_serving_policy` refuses to
serve a network address without a token (unless ``server.insecure``), because anyone on the
Wi-Fi could drive the robot. Pure: reads the config object, imports neither rospy nor Flask.
"""

import logging
import os
import stat

from flask_move_server.core.errors import ConfigError

log = logging.getLogger(__name__)

TOKEN_ENV = "FLASK_MOVE_SERVER_TOKEN"
LOOPBACK_HOSTS = ("127.0.0.1", "localhost", "::1")


def resolved_token(config):
    """The bearer token in force: env var, then ``token``, then ``token_file``; None if none.

    Every source is stripped the same way (a file's newline or a pasted space is not part of
    the secret) and checked: empty or not printable ASCII is a ConfigError (see check_token).
    """
    found = token_source(config)
    if found is None:
        return None
    source, key, text = found
    return check_token(text.strip(), source, key)


def token_source(config):
    """(source, key, raw text) of the token in force, or None; an empty env var counts as unset."""
    env = os.environ.get(TOKEN_ENV, "")
    if env.strip():
        return "environment", TOKEN_ENV, env
    if config.server.token is not None:
        return config.source, "server.token", config.server.token
    if config.server.token_file:
        return config.source, "server.token_file", _read_token_file(config.server.token_file, config.source)
    return None


def serves_only_loopback(config):
    """True when the server binds a loopback address only."""
    return config.server.host in LOOPBACK_HOSTS


def _read_token_file(path, source):
    try:
        with open(path, encoding="utf-8") as f:
            return f.read()
    except OSError as exc:
        raise ConfigError(source, "server.token_file", "cannot read {}: {}".format(path, exc.strerror))
    except UnicodeDecodeError:
        raise ConfigError(source, "server.token_file", "{} is not text (UTF-8)".format(path))


def check_token(token, source, key):
    """``token`` if it can be a bearer token every client sends alike, else ConfigError.

    Non-ASCII is refused rather than half-supported: curl sends a header's bytes as typed (UTF-8),
    browsers and Python's http.client (requests, robotctl) send Latin-1, so such a token would
    work from some clients and not from others.
    """
    if not token:
        raise ConfigError(source, key, "the token is empty; set one, or remove the setting")
    bad = [i for i, c in enumerate(token) if not " " <= c <= "~"]
    if bad:
        raise ConfigError(source, key, "the token has a character that is not printable ASCII (at position {}); "
                          "HTTP clients would send it differently. Use letters, digits and punctuation, e.g. "
                          "python3 -c 'import secrets; print(secrets.token_urlsafe(24))'".format(bad[0] + 1))
    return token


def warn_if_token_file_shared(config):
    """Log a warning when the token in force comes from a file other users can read or change."""
    found = token_source(config)
    if found is None or found[1] != "server.token_file":
        return
    path = config.server.token_file
    mode = stat.S_IMODE(os.stat(path).st_mode)
    if mode & 0o077:
        log.warning("the token file %s can be read by other users of this machine (mode %04o): "
                    "run chmod 600 %s", path, mode, path)


def check_serving_policy(config):
    """At start-up: the token is valid and private; no network address is served without one (unless insecure)."""
    token = resolved_token(config)
    if token:
        warn_if_token_file_shared(config)
    if token or serves_only_loopback(config) or config.server.insecure:
        return
    raise ConfigError(
        config.source,
        "server.token",
        "refusing to serve {} without a token: anyone on the network could drive the robot. "
        "Set {}=<secret> or server.token / server.token_file in the config, "
        "bind --host 127.0.0.1, or pass --insecure on a trusted network".format(config.server.host, TOKEN_ENV),
    )
