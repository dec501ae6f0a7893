"""Deployment files: timing values bounded and finite, TLS files checked before any
session opens (each problem naming the file, its line and the field), and the
CLI commands that read them exit 2 with one line, never a traceback."""

from __future__ import annotations

import datetime
import os
import subprocess
import sys

import pytest

from cosim.distributed.deploy import load_deploy
from cosim.distributed.pem_files import certificate_validity, check_pem_file
from cosim.errors import UserError
from tests.helpers.paths import REPO_ROOT

MAKE_CERTS = REPO_ROOT / "examples" / "tls" / "make_certs.sh"


@pytest.fixture(scope="module")
def certs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("certs")
    subprocess.run(["sh", str(MAKE_CERTS), str(folder), "node", "127.0.0.1"],
                   check=True, capture_output=True)
    return folder


def deploy_error(path) -> str:
    with pytest.raises(UserError) as error:
        load_deploy(path)
    return str(error.value)


@pytest.mark.parametrize("text, message", [
    ("lease_s: .inf\n", "lease_s: Input should be a finite number"),
    ("lease_s: 1e308\n", "lease_s: Input should be less than or equal to 3600"),
    ("lease_s: 0.1\n", "lease_s: Input should be greater than or equal to 0.5"),
    ("open_timeout_s: 1e308\n", "open_timeout_s: Input should be less than or equal to 600"),
    ("open_timeout_s: .nan\n", "open_timeout_s: Input should be a finite number"),
    ("discovery_timeout_s: .inf\n", "discovery_timeout_s: Input should be a finite number"),
    ("discovery_timeout_s: 0\n", "discovery_timeout_s: Input should be greater than 0"),
])
def test_timing_values_are_finite_and_bounded(tmp_path, text, message):
    path = tmp_path / "d.yaml"
    path.write_text("listen: [tcp/127.0.0.1:7447]\n" + text)
    assert deploy_error(path) == f"{path}:2: {message}"


def test_timing_values_at_their_bounds_are_accepted(tmp_path):
    path = tmp_path / "d.yaml"
    path.write_text("lease_s: 3600\nopen_timeout_s: 600\ndiscovery_timeout_s: 600\n")
    settings = load_deploy(path)
    assert (settings.lease_s, settings.open_timeout_s, settings.discovery_timeout_s) == \
        (3600, 600, 600)


def tls_file(tmp_path, certs, **files) -> str:
    """A deployment file whose tls block uses `certs` unless `files` replaces one."""
    chosen = {"root_ca_certificate": certs / "ca.pem", "certificate": certs / "node.pem",
              "private_key": certs / "node-key.pem", **files}
    path = tmp_path / "t.yaml"
    path.write_text("listen: [tls/127.0.0.1:7447]\ntls:\n"
                    + "".join(f"  {k}: {v}\n" for k, v in chosen.items()))
    return path


def test_good_tls_files_are_accepted(tmp_path, certs):
    settings = load_deploy(tls_file(tmp_path, certs))
    assert settings.tls.private_key == str(certs / "node-key.pem")


def test_garbage_certificate_is_named_with_file_line_and_field(tmp_path, certs):
    garbage = tmp_path / "garbage.pem"
    garbage.write_text("-----BEGIN CERTIFICATE-----\nnot base64 !!\n-----END CERTIFICATE-----\n")
    path = tls_file(tmp_path, certs, certificate=garbage)
    assert deploy_error(path) == (f"{path}:4: tls.certificate: {str(garbage)!r} does not hold "
                                  f"a PEM certificate: bad base64 in its CERTIFICATE block")
    garbage.write_text("hello\n")
    assert deploy_error(path) == (f"{path}:4: tls.certificate: {str(garbage)!r} does not hold "
                                  f"a PEM certificate: no -----BEGIN CERTIFICATE----- block")
    garbage.write_text("-----BEGIN CERTIFICATE-----\nAAAA\n-----END CERTIFICATE-----\n")
    assert deploy_error(path) == (f"{path}:4: tls.certificate: certificate {str(garbage)!r} "
                                  f"is not an X.509 certificate: bad DER encoding (truncated certificate)")
    path = tls_file(tmp_path, certs, root_ca_certificate=certs / "node-key.pem")
    assert "tls.root_ca_certificate: " in deploy_error(path)
    assert "no -----BEGIN CERTIFICATE----- block" in deploy_error(path)


def test_private_key_must_be_owner_only_and_a_key(tmp_path, certs):
    key = tmp_path / "key.pem"
    key.write_bytes((certs / "node-key.pem").read_bytes())
    key.chmod(0o644)
    path = tls_file(tmp_path, certs, private_key=key)
    assert deploy_error(path) == (f"{path}:5: tls.private_key: private key {str(key)!r} is "
                                  f"readable by others (mode 644); make it owner-only: "
                                  f"chmod 600 {key}")
    key.chmod(0o600)
    assert load_deploy(path).tls.private_key == str(key)
    text = tmp_path / "text.pem"
    text.write_bytes((certs / "node.pem").read_bytes())
    text.chmod(0o600)
    path = tls_file(tmp_path, certs, private_key=text)
    assert deploy_error(path) == (
        f"{path}:5: tls.private_key: {str(text)!r} does not hold a PEM private key: expected "
        f"one -----BEGIN PRIVATE KEY----- block (or RSA/EC PRIVATE KEY, unencrypted) "
        f"(found CERTIFICATE)")


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads every file")
def test_unreadable_certificate_is_named(tmp_path, certs):
    unreadable = tmp_path / "node.pem"
    unreadable.write_bytes((certs / "node.pem").read_bytes())
    unreadable.chmod(0)
    path = tls_file(tmp_path, certs, certificate=unreadable)
    assert deploy_error(path) == (f"{path}:4: tls.certificate: cannot read "
                                  f"{str(unreadable)!r}: Permission denied")


def test_certificate_validity_is_checked(certs):
    body = (certs / "node.pem").read_text()
    import base64
    der = base64.b64decode("".join(body.split("-----")[2].split()))
    not_before, not_after = certificate_validity(der)
    assert datetime.timedelta(days=29) < not_after - not_before <= datetime.timedelta(days=31)
    assert check_pem_file(certs / "node.pem", private=False) == ""
    later = not_after + datetime.timedelta(seconds=1)
    assert check_pem_file(certs / "node.pem", private=False, now=later) == (
        f"certificate {str(certs / 'node.pem')!r} expired on {not_after:%Y-%m-%d %H:%M:%S} UTC")
    earlier = not_before - datetime.timedelta(seconds=1)
    assert check_pem_file(certs / "node.pem", private=False, now=earlier) == (
        f"certificate {str(certs / 'node.pem')!r} is not valid before "
        f"{not_before:%Y-%m-%d %H:%M:%S} UTC")


def run_cli(*args: str, timeout: float = 60) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "cosim.cli.app", *args], cwd=REPO_ROOT,
                          capture_output=True, text=True, timeout=timeout)


@pytest.mark.parametrize("command", [
    ["worker", "--name", "wx", "--listen", "tcp/127.0.0.1:0", "--insecure"],
    ["workers"],
    ["router", "--listen", "tcp/127.0.0.1:0"],
    ["run", "lane_change", "--no-figures", "--listen", "tcp/127.0.0.1:0",
     "--place", "controller=nosuch"],
])
def test_commands_refuse_an_infinite_lease_with_one_line(tmp_path, command):
    deploy = tmp_path / "d.yaml"
    deploy.write_text("lease_s: .inf\n")
    extra = ["--out", str(tmp_path / "out")] if command[0] == "run" else []
    done = run_cli(*command, *extra, "--deploy", str(deploy))
    assert done.returncode == 2, done.stderr
    assert "Traceback" not in done.stderr + done.stdout
    assert f"{deploy}:1: lease_s: Input should be a finite number" in done.stderr + done.stdout
