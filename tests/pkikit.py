"""Test certificates for zenoh's TLS transport, made with the ``openssl`` CLI.

EC P-256 keys; each leaf has ``subjectAltName=IP:127.0.0.1,DNS:localhost`` (for
``verify_name_on_connect``) and server+client usage (mutual TLS), valid two days.
:func:`tls_files` points a zenoh config at a node's files.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import zenoh


def _openssl(*args: str, cwd: Path) -> None:
    subprocess.run(["openssl", *args], cwd=cwd, check=True, capture_output=True, timeout=60)


def make_ca(directory: Path, name: str) -> None:
    """``<name>.pem`` and ``<name>-key.pem``: a self-signed CA."""
    _openssl(
        "req", "-x509", "-new", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:P-256",
        "-nodes", "-keyout", f"{name}-key.pem", "-out", f"{name}.pem", "-days", "2",
        "-subj", f"/CN={name}", "-set_serial", "1",
        "-addext", "basicConstraints=critical,CA:TRUE",
        "-addext", "keyUsage=critical,keyCertSign,cRLSign",
        cwd=directory,
    )  # fmt: skip


def make_leaf(directory: Path, ca: str, common_name: str, serial: int) -> None:
    """``<common_name>.pem`` and ``-key.pem`` signed by the CA ``ca`` (see :func:`make_ca`)."""
    extensions = directory / f"{common_name}.ext"
    extensions.write_text(
        "basicConstraints=critical,CA:FALSE\n"
        "keyUsage=critical,digitalSignature\n"
        "extendedKeyUsage=serverAuth,clientAuth\n"
        "subjectAltName=IP:127.0.0.1,DNS:localhost\n"
    )
    _openssl(
        "req", "-new", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:P-256", "-nodes",
        "-keyout", f"{common_name}-key.pem", "-out", f"{common_name}.csr",
        "-subj", f"/CN={common_name}",
        cwd=directory,
    )  # fmt: skip
    _openssl(
        "x509", "-req", "-in", f"{common_name}.csr", "-CA", f"{ca}.pem",
        "-CAkey", f"{ca}-key.pem", "-set_serial", str(serial), "-days", "2",
        "-extfile", extensions.name, "-out", f"{common_name}.pem",
        cwd=directory,
    )  # fmt: skip


def tls_files(config: zenoh.Config, pki: Path, ca: str, name: str) -> None:
    """Point ``config``'s TLS CA, certificate and key (both directions) at ``pki``."""
    config.insert_json5(
        "transport/link/tls/root_ca_certificate", json.dumps(str(pki / f"{ca}.pem"))
    )
    for direction in ("listen", "connect"):
        config.insert_json5(
            f"transport/link/tls/{direction}_certificate", json.dumps(str(pki / f"{name}.pem"))
        )
        config.insert_json5(
            f"transport/link/tls/{direction}_private_key", json.dumps(str(pki / f"{name}-key.pem"))
        )


def make_pki(directory: Path, leaves: tuple[str, ...], rogue: str) -> Path:
    """``test-ca`` signing ``leaves`` (serials 2, 3, …) and ``rogue-ca`` signing ``rogue``
    (serial 9), all in ``directory``; the caller skips when openssl is missing."""
    make_ca(directory, "test-ca")
    make_ca(directory, "rogue-ca")
    for serial, name in enumerate(leaves, start=2):
        make_leaf(directory, "test-ca", name, serial)
    make_leaf(directory, "rogue-ca", rogue, 9)
    return directory
