"""Deployment settings of distributed runs: endpoints, TLS and access control.

These settings describe the network, not the experiment, so they live in their
own YAML file (`--deploy FILE`), never in the scenario:

    listen: [tls/10.0.0.1:7447]          # where this process accepts Zenoh links
    connect: [tls/10.0.0.2:7447]         # workers or a router to join
    tls:                                 # all paths relative to this file
      root_ca_certificate: ca.pem        # CA that signed every peer's certificate
      certificate: node.pem              # this node's certificate (listen and connect)
      private_key: node-key.pem
      mutual: true                       # peers must present a certificate too
      verify_name: false                 # check the endpoint's name against the cert
    auth:                                # a shared credential (Zenoh user-password)
      credentials_file: cosim.credential # one line "user:password", owner-only (chmod 600)
    access_control:                      # Zenoh's own ACL block, passed as is
      enabled: true
      default_permission: deny
      rules: [...]
      subjects: [...]
      policies: [...]
    discovery_timeout_s: 3.0             # how long the master looks for its workers (0-600 s]
    lease_s: 2.0                         # a silent link (cut cable) is dropped after this [0.5-3600 s]
    open_timeout_s: 1.0                  # longest attempt to open a link, bounds close too (0-600 s]

The timings must be finite numbers within the bounds above. The TLS files are
checked when the file is read, each problem naming the file, its line and the
field: readable, PEM (BEGIN/END markers around base64), certificates that parse
as X.509 and are valid now (not expired, not yet valid), and a private key that
neither group nor others may read (like the credentials file). Whether the key
matches its certificate is left to the TLS handshake.

A node with `auth` presents the shared credential and accepts the peers that
present it (the credentials file is also its Zenoh dictionary file).
`zenoh_config` turns settings plus a mode and endpoints into a `zenoh.Config`;
every session of the distributed platform (master, worker, component
process, router, `cosim workers`) is built through it, so TLS and ACL apply
to all of them alike.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Optional

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from cosim.distributed.pem_files import check_pem_file
from cosim.errors import Problem, ProblemsError, UserError
from cosim.scenario.yaml_lines import LineMap, load_yaml, read_yaml_file
from cosim.transport.zenoh.auth import Credential, read_credential_file

_PROTOCOLS = ("tcp", "tls", "udp", "quic", "unixsock-stream")
MAX_DISCOVERY_TIMEOUT_S = 600.0
MAX_LEASE_S = 3600.0
MAX_OPEN_TIMEOUT_S = 600.0


class TlsSettings(BaseModel):
    """Certificates of one node (paths resolved against the deployment file)."""

    model_config = ConfigDict(extra="forbid")
    root_ca_certificate: str
    certificate: str
    private_key: str
    mutual: bool = True
    verify_name: bool = False


class AuthSettings(BaseModel):
    """A credential shared by the hosts of a deployment (path resolved against the file)."""

    model_config = ConfigDict(extra="forbid")
    credentials_file: str


class DeploySettings(BaseModel):
    """The whole deployment file (see the module docstring)."""

    model_config = ConfigDict(extra="forbid")
    listen: list[str] = Field(default_factory=list)
    connect: list[str] = Field(default_factory=list)
    tls: Optional[TlsSettings] = None
    auth: Optional[AuthSettings] = None
    access_control: Optional[dict[str, Any]] = None
    discovery_timeout_s: float = Field(3.0, gt=0, le=MAX_DISCOVERY_TIMEOUT_S, allow_inf_nan=False)
    lease_s: float = Field(2.0, ge=0.5, le=MAX_LEASE_S, allow_inf_nan=False)
    open_timeout_s: float = Field(1.0, gt=0, le=MAX_OPEN_TIMEOUT_S, allow_inf_nan=False)

    def credential(self) -> Credential | None:
        """The shared credential of `auth` (read now; UserError when the file is unsafe)."""
        return read_credential_file(self.auth.credentials_file) if self.auth else None

    def authenticates_peers(self) -> bool:
        """Whether a session with these settings accepts only peers it can authenticate
        (a shared credential, or TLS that asks for client certificates)."""
        return self.auth is not None or (self.tls is not None and self.tls.mutual)

    @field_validator("listen", "connect")
    @classmethod
    def _endpoints(cls, values: list[str]) -> list[str]:
        for value in values:
            check_endpoint(value)
        return values


def check_endpoint(endpoint: str) -> str:
    """Return `endpoint` if it looks like a Zenoh endpoint "proto/address", else raise ValueError.

    Args:
        endpoint: e.g. "tcp/10.0.0.1:7447" or "tls/host.example:7447".
    """
    proto, sep, address = str(endpoint).partition("/")
    if not sep or proto not in _PROTOCOLS or not address:
        raise ValueError(f"endpoint {endpoint!r} is not of the form PROTOCOL/ADDRESS "
                         f"with PROTOCOL one of {', '.join(_PROTOCOLS)}")
    return endpoint


def load_deploy(path: str | Path) -> DeploySettings:
    """Read a deployment file; certificate paths become absolute (relative to the file).

    Args:
        path: the YAML file.
    Raises:
        UserError naming the file, the line and each bad field ("FILE:LINE: FIELD: ...").
    """
    path = Path(path)
    try:  # bounded and checked like a scenario file (size, UTF-8, NUL, nesting)
        document, lines, problems = load_yaml(read_yaml_file(path))
    except (OSError, yaml.YAMLError, RecursionError) as exc:
        reason = getattr(exc, "problem", None) or exc
        raise UserError(f"{path}: cannot read deployment file: {reason}") from None
    if problems:
        raise ProblemsError(path, problems)
    document = document if document is not None else {}
    if not isinstance(document, dict):
        raise UserError(f"{path}: a deployment file is a mapping (listen, connect, tls, "
                        f"access_control), got {type(document).__name__}")
    try:
        settings = DeploySettings.model_validate(document)
    except ValidationError as exc:
        raise ProblemsError(path, [Problem(".".join(str(p) for p in e["loc"]),
                                           lines.line_of(e["loc"]), e["msg"])
                                   for e in exc.errors()]) from None
    if settings.tls is not None:
        settings.tls = _resolve_tls(settings.tls, path, lines)
    if settings.auth is not None:
        file = Path(settings.auth.credentials_file)
        file = file if file.is_absolute() else path.parent / file
        settings.auth = AuthSettings(credentials_file=str(file.resolve()))
        settings.credential()  # a missing or unsafe file is reported now, naming it
    return settings


def _resolve_tls(tls: TlsSettings, path: Path, lines: LineMap) -> TlsSettings:
    """The TLS settings with absolute paths, every file checked (see the module docstring)."""
    resolved = {}
    for field in ("root_ca_certificate", "certificate", "private_key"):
        file = Path(getattr(tls, field))
        file = file if file.is_absolute() else (path.parent / file)
        problem = (f"no such file {str(file)!r}" if not file.is_file()
                   else check_pem_file(file, private=field == "private_key"))
        if problem:
            raise ProblemsError(path, [Problem(f"tls.{field}", lines.line_of(("tls", field)),
                                               problem)])
        resolved[field] = str(file.resolve())
    return tls.model_copy(update=resolved)


def merge_endpoints(settings: DeploySettings | None, listen: list[str] | None = None,
                    connect: list[str] | None = None) -> DeploySettings:
    """Settings with command-line endpoints added (command line first).

    Args:
        settings: from a deployment file, or None for defaults.
        listen / connect: endpoints given on the command line.
    Raises:
        UserError for an endpoint that is not PROTOCOL/ADDRESS.
    """
    base = settings or DeploySettings()
    try:
        for value in [*(listen or []), *(connect or [])]:
            check_endpoint(value)
    except ValueError as exc:
        raise UserError(str(exc)) from None
    return base.model_copy(update={
        "listen": _unique([*(listen or []), *base.listen]),
        "connect": _unique([*(connect or []), *base.connect])})


def _unique(values: list[str]) -> list[str]:
    return list(dict.fromkeys(values))


def session_mode(listen: list[str], connect: list[str]) -> str:
    """"client" for a node that listens nowhere and joins one endpoint (a router), else "peer".

    A router forwards for its clients but not between peers that cannot reach
    each other (Zenoh's peer-to-peer routing), so a node behind a router is a client.

    Args:
        listen / connect: the node's endpoints.
    """
    return "client" if not listen and len(connect) == 1 else "peer"


def zenoh_settings(settings: DeploySettings | None, mode: str, listen: list[str],
                   connect: list[str]) -> dict[str, Any]:
    """The Zenoh configuration document (a dict) for one session.

    Args:
        settings: TLS and ACL to apply (None: plain).
        mode: "peer", "client" or "router".
        listen / connect: the session's endpoints.
    """
    document: dict[str, Any] = {
        "mode": mode,
        "listen": {"endpoints": list(listen)},
        "connect": {"endpoints": list(connect)},
        "scouting": {"multicast": {"enabled": False}, "gossip": {"enabled": False}},
    }
    timing = settings or DeploySettings()
    link: dict[str, Any] = {"tx": {"lease": int(timing.lease_s * 1000)}}
    # a session waits for a pending connect attempt when it closes: keep attempts short
    document["transport"] = {"link": link,
                             "unicast": {"open_timeout": int(timing.open_timeout_s * 1000)}}
    if settings is not None and settings.tls is not None:
        tls = settings.tls
        link["tls"] = {
            "root_ca_certificate": tls.root_ca_certificate,
            "listen_certificate": tls.certificate, "listen_private_key": tls.private_key,
            "connect_certificate": tls.certificate, "connect_private_key": tls.private_key,
            "enable_mtls": tls.mutual, "verify_name_on_connect": tls.verify_name}
    if settings is not None and settings.auth is not None:
        shared = settings.credential()
        assert shared is not None
        document["transport"]["auth"] = {
            "usrpwd": shared.usrpwd(settings.auth.credentials_file)}
    if settings is not None and settings.access_control is not None:
        document["access_control"] = settings.access_control
    return document


def zenoh_config(settings: DeploySettings | None, mode: str, listen: list[str],
                 connect: list[str]) -> Any:
    """A `zenoh.Config` for one session (see `zenoh_settings` for the arguments).

    Raises:
        UserError when Zenoh rejects the configuration (bad ACL block, say).
    """
    return to_zenoh_config(zenoh_settings(settings, mode, listen, connect))


def to_zenoh_config(document: dict[str, Any]) -> Any:
    """A `zenoh.Config` from a configuration document (`zenoh_settings`, maybe amended).

    Raises:
        UserError when Zenoh rejects it.
    """
    import zenoh

    try:
        return zenoh.Config.from_json5(json.dumps(document))
    except zenoh.ZError as exc:
        raise UserError(f"invalid Zenoh configuration from the deployment settings: {exc}") from None
