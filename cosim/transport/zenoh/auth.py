"""Credentials of a run's Zenoh sessions: Zenoh's user-password authentication
(`transport/auth/usrpwd`) and an access-control list scoped to the run's keys.

A run generates its own credential (`new_credential`). The master's session
accepts only peers that prove it (its dictionary file, owner-only, in a private
temporary folder: `Dictionary`); component processes get it on their stdin,
`cosim watch` from the owner-only `live.credential` file of the run folder, so
it is never on a command line. Zenoh checks it with a challenge (the password
itself never travels), and a peer without it cannot open a link: it neither
sees nor sends anything. The ACL (`run_acl`) then lets authenticated peers
use only the run's own key space.

A shared credential (a deployment file's `auth: {credentials_file: F}`) is one
line "user:password" in a file only its owner may read (`read_credential_file`).
This module needs only the standard library (the master spawns processes before
it loads zenoh).
"""

from __future__ import annotations

import base64
import os
import stat
import tempfile
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cosim.errors import UserError

LIVE_CREDENTIAL_FILE = "live.credential"
MESSAGES = ["put", "delete", "declare_subscriber", "query", "reply", "declare_queryable",
            "liveliness_token", "liveliness_query", "declare_liveliness_subscriber"]


@dataclass(frozen=True)
class Credential:
    """A Zenoh user and password (neither may contain ':' or a line break)."""

    user: str
    password: str

    def line(self) -> str:
        """The credential as one line of a Zenoh dictionary file."""
        return f"{self.user}:{self.password}\n"

    def usrpwd(self, dictionary_file: str | None = None) -> dict[str, Any]:
        """The `transport/auth/usrpwd` block: present this credential, and accept the
        peers listed in `dictionary_file` (None: a session that only connects)."""
        block: dict[str, Any] = {"user": self.user, "password": self.password}
        if dictionary_file:
            block["dictionary_file"] = dictionary_file
        return block

    def to_json(self) -> dict[str, str]:
        """The credential as a JSON object (for a component's stdin)."""
        return {"user": self.user, "password": self.password}

    @classmethod
    def from_json(cls, document: Any) -> "Credential | None":
        """A credential from `to_json`'s object, or None for None."""
        if document is None:
            return None
        return cls(str(document["user"]), str(document["password"]))


def new_credential(run_id: str) -> Credential:
    """A fresh random credential for run `run_id` (256 bits of password; os.urandom
    rather than `secrets`, whose imports cost the start-up some milliseconds)."""
    password = base64.urlsafe_b64encode(os.urandom(32)).rstrip(b"=").decode()
    return Credential(f"run-{run_id}", password)


def write_private(path: Path, text: str) -> None:
    """Create `path` readable and writable by its owner only (0600), holding `text`.

    Raises:
        OSError when the file exists already (never write through a planted file).
    """
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0),
                 0o600)
    with os.fdopen(fd, "w") as file:
        file.write(text)


def write_credential_file(path: Path, credential: Credential) -> None:
    """Write `credential` as a one-line owner-only file (what `read_credential_file` reads)."""
    write_private(path, credential.line())


def read_credential_file(path: str | Path) -> Credential:
    """The credential of a one-line "user:password" file that only its owner may read.

    Args:
        path: the file.
    Raises:
        UserError naming the file when it cannot be read, is readable by others,
        belongs to another user or is not one "user:password" line.
    """
    path = Path(path)
    try:
        info = path.stat()
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"{path}: cannot read the credential file: {exc}") from None
    if info.st_mode & (stat.S_IRWXG | stat.S_IRWXO):
        raise UserError(f"{path}: the credential file is readable by others "
                        f"(mode {stat.S_IMODE(info.st_mode):o}); make it owner-only: "
                        f"chmod 600 {path}")
    if info.st_uid != os.getuid():
        raise UserError(f"{path}: the credential file belongs to another user")
    lines = [line for line in text.splitlines() if line.strip()]
    user, sep, password = (lines[0] if len(lines) == 1 else "").partition(":")
    if not sep or not user or not password or ":" in password:
        raise UserError(f"{path}: a credential file holds one line 'user:password' "
                        f"(no ':' inside either)")
    return Credential(user.strip(), password.strip())


class Dictionary:
    """The owner-only dictionary file of a master's session, in a private temporary
    folder (0700) that `close` removes.

    Args:
        credentials: every credential the session accepts.
    """

    def __init__(self, credentials: Iterable[Credential]) -> None:
        self._folder = Path(tempfile.mkdtemp(prefix="cosim-auth-"))
        self.path = self._folder / "users"
        write_private(self.path, "".join(c.line() for c in credentials))

    def close(self) -> None:
        """Remove the file and its folder."""
        import shutil

        shutil.rmtree(self._folder, ignore_errors=True)


def run_acl(run_id: str, also: Sequence[str] = ()) -> dict[str, Any]:
    """An `access_control` block allowing every message only under the run's keys.

    Args:
        run_id: the run; its key space is `cosim/<run_id>/**`.
        also: more key expressions to allow (the workers' keys, for a distributed run).
    """
    return {"enabled": True, "default_permission": "deny",
            "rules": [{"id": "run", "permission": "allow", "flows": ["egress", "ingress"],
                       "messages": MESSAGES, "key_exprs": [f"cosim/{run_id}/**", *also]},
                      # `cosim watch '*'`: the subscription may name any run; what the
                      # master sends it is still only this run's (the rule above)
                      {"id": "watch_any", "permission": "allow", "flows": ["ingress"],
                       "messages": ["declare_subscriber"], "key_exprs": ["cosim/*/live/data"]}],
            "subjects": [{"id": "every_peer"}],
            "policies": [{"rules": ["run", "watch_any"], "subjects": ["every_peer"]}]}


def security_settings(credential: Credential | None, dictionary_file: str | None = None,
                      acl_run_id: str | None = None) -> dict[str, Any]:
    """The part of a Zenoh config document that authenticates a session.

    Args:
        credential: what the session presents (None: nothing, a plain session).
        dictionary_file: whom it accepts (a listening session), or None.
        acl_run_id: restrict the session to this run's keys (None: no ACL).
    """
    document: dict[str, Any] = {}
    if credential is not None:
        document["transport"] = {"auth": {"usrpwd": credential.usrpwd(dictionary_file)}}
    if acl_run_id is not None:
        document["access_control"] = run_acl(acl_run_id)
    return document
