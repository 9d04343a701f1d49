"""TLS for the headset page: a self-signed certificate and this machine's LAN addresses.

The Quest Browser only grants WebXR to secure origins. :func:`ensure_certificate` makes a
self-signed certificate for ``localhost`` and this machine's addresses (kept and reused while it
is valid and covers them, so the headset's one-time "proceed anyway" stays accepted); the
alternative is plain HTTP to ``localhost`` through ``adb reverse tcp:8443 tcp:8443`` (a secure
context too). :func:`local_addresses` lists the addresses a headset on the LAN may open.

The private key is created with mode 0600 (never briefly world-readable), and a reused key file
that others may read is tightened to 0600 with a warning, or refused when that fails.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import ipaddress
import logging
import os
import socket
import stat
from pathlib import Path

from teleop.input.background_server import WebIngestError

__all__ = ["default_cert_dir", "ensure_certificate", "local_addresses"]

logger = logging.getLogger(__name__)


def local_addresses() -> list[str]:
    """This machine's IPv4 addresses a headset on the LAN may use (loopback first). Uses no
    network traffic: a UDP socket "connected" to a private address only picks a route."""
    out = ["127.0.0.1"]
    with contextlib.suppress(OSError):
        for info in socket.getaddrinfo(socket.gethostname(), None, socket.AF_INET):
            out.append(str(info[4][0]))
    for probe in ("10.255.255.255", "192.168.255.255"):
        with contextlib.suppress(OSError), socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.connect((probe, 1))
            out.append(s.getsockname()[0])
    return list(dict.fromkeys(a for a in out if a != "0.0.0.0"))


def default_cert_dir() -> Path:
    """``$DEXAUG_CACHE_DIR/web-cert`` (default ``~/.cache/dexaug/web-cert``)."""
    root = os.environ.get("DEXAUG_CACHE_DIR") or Path.home() / ".cache" / "dexaug"
    return Path(root) / "web-cert"


def _write_private(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` readable by its owner only: created 0600, and an existing file
    is made 0600 before a byte of the key goes in."""
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    os.fchmod(fd, 0o600)
    with os.fdopen(fd, "wb") as f:
        f.write(data)


def _check_private(path: Path) -> None:
    """A reused key must be its owner's alone: looser modes are fixed to 0600 (with a warning),
    or a :class:`WebIngestError` says what to do when they cannot be."""
    mode = stat.S_IMODE(path.stat().st_mode)
    if not mode & 0o077:
        return
    try:
        path.chmod(0o600)
    except OSError as exc:
        raise WebIngestError(f"{path}: the private key is readable by other users (mode "
                             f"{mode:#o}) and cannot be made 0600 ({exc.strerror}); chmod 600 "
                             "it or delete it") from None
    logger.warning("%s: the private key was readable by other users (mode %#o); made it 0600",
                   path, mode)


def ensure_certificate(cert_dir: Path | str | None = None, *, hosts: list[str] | None = None,
                       valid_days: int = 825) -> tuple[Path, Path]:
    """``(cert.pem, key.pem)`` in ``cert_dir``: a self-signed certificate for ``localhost``, the
    machine's host name and ``hosts`` (default: :func:`local_addresses`). An existing one is
    reused while it is valid for another day and covers those names, so a headset that accepted
    it once is not asked again; otherwise a new one (EC P-256) replaces it. The key is 0600
    (module docstring)."""
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import NameOID

    d = Path(cert_dir) if cert_dir is not None else default_cert_dir()
    cert_path, key_path = d / "cert.pem", d / "key.pem"
    ips = hosts if hosts is not None else local_addresses()
    dns = ["localhost", socket.gethostname()]
    now = dt.datetime.now(dt.UTC)
    if cert_path.is_file() and key_path.is_file():
        try:
            old = x509.load_pem_x509_certificate(cert_path.read_bytes())
            san = old.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
            have = {str(v) for v in san.get_values_for_type(x509.IPAddress)} | \
                set(san.get_values_for_type(x509.DNSName))
            if old.not_valid_after_utc > now + dt.timedelta(days=1) and \
                    set(ips) | set(dns) <= have:
                _check_private(key_path)
                return cert_path, key_path
            logger.info("%s: does not cover %s or expires soon; making a new one", cert_path,
                        sorted(set(ips) | set(dns) - have))
        except (ValueError, x509.ExtensionNotFound) as exc:
            logger.warning("%s: unreadable certificate (%s); making a new one", cert_path, exc)
    d.mkdir(parents=True, exist_ok=True, mode=0o700)
    key = ec.generate_private_key(ec.SECP256R1())
    name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "dexaug bridge (self-signed)")])
    alt = [x509.DNSName(n) for n in dns] + [x509.IPAddress(ipaddress.ip_address(a)) for a in ips]
    cert = (x509.CertificateBuilder().subject_name(name).issuer_name(name)
            .public_key(key.public_key()).serial_number(x509.random_serial_number())
            .not_valid_before(now - dt.timedelta(minutes=5))
            .not_valid_after(now + dt.timedelta(days=valid_days))
            .add_extension(x509.SubjectAlternativeName(alt), critical=False)
            .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
            .sign(key, hashes.SHA256()))
    _write_private(key_path, key.private_bytes(serialization.Encoding.PEM,
                                               serialization.PrivateFormat.PKCS8,
                                               serialization.NoEncryption()))
    cert_path.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    logger.info("wrote a self-signed certificate %s for %s", cert_path, ", ".join(dns + ips))
    return cert_path, key_path
