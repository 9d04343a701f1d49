"""One network-access policy (issue #51): every server decides loopback, the token rule, the
token compare, Host and Origin with the functions of :mod:`teleop.net_access`, and nowhere in
the package is a second implementation of them."""

from __future__ import annotations

import re
import subprocess

import pytest

from sim.paths import REPO_ROOT
from teleop import net_access


def test_the_servers_share_the_same_function_objects() -> None:
    from dexaug.dashboard import guard
    from teleop.bridge import foxglove_live
    from teleop.input import access, stream_ingest

    assert guard.is_loopback is access.is_loopback is net_access.is_loopback
    assert stream_ingest.is_loopback is foxglove_live.is_loopback is net_access.is_loopback
    for name in ("host_ok", "origin_ok", "token_ok", "token_required", "new_token"):
        assert getattr(guard, name) is getattr(access, name) is getattr(net_access, name), name
    assert guard.WILDCARDS is access.WILDCARDS is net_access.WILDCARDS


def _package_sources() -> dict[str, str]:
    files = subprocess.run(["git", "ls-files", "--cached", "--others", "--exclude-standard",
                            "*.py"], cwd=REPO_ROOT, capture_output=True, text=True,
                           check=True).stdout.split()
    return {f: (REPO_ROOT / f).read_text() for f in files
            if f.split("/")[0] in ("sim", "augment", "teleop", "dexaug") and (REPO_ROOT / f).is_file()}


@pytest.mark.parametrize("pattern", [r"^\s*def is_loopback\b", r"compare_digest\(",
                                     r"ip_address\(.*\)\.is_loopback",
                                     r"^\s*def _?host_name\b", r"token_urlsafe\("])
def test_no_second_implementation_in_the_package(pattern: str) -> None:
    where = sorted(f for f, text in _package_sources().items()
                   if re.search(pattern, text, re.MULTILINE))
    assert where == ["teleop/net_access.py"], where


@pytest.mark.parametrize(("host", "loopback"), [
    ("127.0.0.1", True), ("127.1.2.3", True), ("::1", True), ("[::1]", True),
    ("localhost", True), (" LocalHost ", True), ("0.0.0.0", False), ("::", False), ("", False),
    ("192.168.1.5", False), ("example.org", False)])
def test_loopback_and_the_token_rule(host: str, loopback: bool) -> None:
    assert net_access.is_loopback(host) is loopback
    assert net_access.token_required(host) is not loopback
    assert net_access.token_required(host, "given-token")


def test_host_origin_and_token_checks() -> None:
    names = frozenset({"localhost", "127.0.0.1", "::1"})
    assert net_access.host_ok("localhost:8080", names) and net_access.host_ok("[::1]:1", names)
    assert not net_access.host_ok("evil.example:8080", names)
    assert not net_access.host_ok("", names) and not net_access.host_ok(None, names)
    assert net_access.host_ok("10.0.0.7:80", names, arrived_on="::ffff:10.0.0.7")
    assert not net_access.host_ok("10.0.0.8:80", names, arrived_on="10.0.0.7")
    assert net_access.origin_ok(None, "http", "localhost:1")
    assert net_access.origin_ok("HTTP://LocalHost:1", "http", "localhost:1")
    assert not net_access.origin_ok("http://evil.example", "http", "localhost:1")
    assert not net_access.origin_ok("https://localhost:1", "http", "localhost:1")
    token = net_access.new_token()
    assert len(token) >= 24 and token != net_access.new_token()
    assert net_access.token_ok(token, token) and not net_access.token_ok(token[:-1], token)
    assert not net_access.token_ok(None, token) and not net_access.token_ok(token, None)
    assert not net_access.token_ok(123, token)
