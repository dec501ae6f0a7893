"""A credential shared by the distributed tests' workers and masters (as a
deployment file's `auth:` gives one): an owner-only file, made once per session."""

from __future__ import annotations

import functools
import tempfile
from pathlib import Path

from cosim.distributed.deploy import AuthSettings
from cosim.transport.zenoh.auth import new_credential, write_credential_file


@functools.lru_cache(maxsize=None)
def shared_credentials_file() -> Path:
    """The file ("user:password", mode 0600), in a private temporary folder."""
    path = Path(tempfile.mkdtemp(prefix="cosim-test-auth-")) / "cosim.credential"
    write_credential_file(path, new_credential("tests"))
    return path


def shared_auth() -> AuthSettings:
    """The `auth:` block of deployment settings using the shared test credential."""
    return AuthSettings(credentials_file=str(shared_credentials_file()))


def auth_deploy_file(folder: Path, name: str = "deploy.yaml") -> Path:
    """A deployment file holding only the shared test credential (`--deploy`)."""
    path = Path(folder) / name
    path.write_text(f"auth: {{credentials_file: {shared_credentials_file()}}}\n")
    return path
