"""TLS files of a deployment, checked before any session opens (`cosim.distributed.deploy`).

Zenoh reads the certificate and key files only when a session connects, and then
says "invalid peer certificate: BadEncoding" or "not reachable" without naming
the file. `check_pem_file` says first what is wrong with one: unreadable, no PEM
block, bad base64, a certificate that is no X.509 or is outside its validity
dates, a private key that group or others can read. The validity dates are read
from the DER structure by hand (`certificate_validity`; no signature check), since
no crypto library is a dependency.
"""

from __future__ import annotations

import base64
import binascii
import datetime
import os
import re
import stat
from pathlib import Path

MAX_PEM_BYTES = 1024 * 1024
_PEM_BLOCK = re.compile(r"-----BEGIN ([A-Z0-9 ]+)-----(.*?)-----END \1-----", re.DOTALL)
_KEY_LABELS = ("PRIVATE KEY", "RSA PRIVATE KEY", "EC PRIVATE KEY")


def check_pem_file(file: Path, private: bool,
                   now: datetime.datetime | None = None) -> str:
    """Why a TLS file cannot serve, or "" when it looks right.

    A certificate file must hold PEM CERTIFICATE blocks that parse as X.509 and
    are valid at `now`; a private key file one PEM private key (PKCS#8, RSA or
    EC) that neither group nor others can read.

    Args:
        file: the PEM file.
        private: True for a private key, False for certificates.
        now: the time certificates must be valid at (default: now, UTC).
    """
    try:
        info = file.stat()
        with open(file, "rb") as handle:
            data = handle.read(MAX_PEM_BYTES + 1)
    except OSError as exc:
        return f"cannot read {str(file)!r}: {exc.strerror or exc}"
    if private and info.st_mode & (stat.S_IRWXG | stat.S_IRWXO):
        return (f"private key {str(file)!r} is readable by others (mode "
                f"{stat.S_IMODE(info.st_mode):o}); make it owner-only: chmod 600 {file}")
    if private and info.st_uid != os.getuid():
        return f"private key {str(file)!r} belongs to another user"
    if len(data) > MAX_PEM_BYTES:
        return f"{str(file)!r} is larger than {MAX_PEM_BYTES} bytes: not a PEM file"
    what = "a PEM private key" if private else "a PEM certificate"
    blocks = []
    for match in _PEM_BLOCK.finditer(data.decode("ascii", errors="replace")):
        try:
            body = base64.b64decode("".join(match.group(2).split()), validate=True)
        except (binascii.Error, ValueError):
            return f"{str(file)!r} does not hold {what}: bad base64 in its {match.group(1)} block"
        if not body:
            return f"{str(file)!r} does not hold {what}: its {match.group(1)} block is empty"
        blocks.append((match.group(1), body))
    if private:
        keys = [label for label, _ in blocks if label in _KEY_LABELS]
        if len(keys) != 1:
            found = f" (found {', '.join(label for label, _ in blocks)})" if blocks else ""
            return (f"{str(file)!r} does not hold {what}: expected one -----BEGIN PRIVATE KEY----- "
                    f"block (or RSA/EC PRIVATE KEY, unencrypted){found}")
        return ""
    certificates = [body for label, body in blocks if label == "CERTIFICATE"]
    if not certificates:
        return f"{str(file)!r} does not hold {what}: no -----BEGIN CERTIFICATE----- block"
    now = now or datetime.datetime.now(datetime.timezone.utc)
    for index, body in enumerate(certificates):
        which = f"certificate {index + 1} of {str(file)!r}" if len(certificates) > 1 \
            else f"certificate {str(file)!r}"
        try:
            not_before, not_after = certificate_validity(body)
        except ValueError as exc:
            return f"{which} is not an X.509 certificate: {exc}"
        if now > not_after:
            return f"{which} expired on {not_after:%Y-%m-%d %H:%M:%S} UTC"
        if now < not_before:
            return f"{which} is not valid before {not_before:%Y-%m-%d %H:%M:%S} UTC"
    return ""


def certificate_validity(der: bytes) -> tuple[datetime.datetime, datetime.datetime]:
    """(notBefore, notAfter) of a DER X.509 certificate, as aware UTC datetimes.

    Reads only the DER structure down to the validity field (no signature check).

    Args:
        der: the certificate's bytes (the base64 body of a PEM block).
    Raises:
        ValueError saying where the encoding is wrong.
    """
    certificate = _der_children(der, 0, len(der), "certificate")[0]
    if certificate[0] != 0x30:
        raise ValueError("bad DER encoding (not a SEQUENCE)")
    tbs = _der_children(der, certificate[1], certificate[2], "certificate")[0]
    fields = _der_children(der, tbs[1], tbs[2], "tbsCertificate")
    if fields and fields[0][0] == 0xA0:  # [0] version
        fields = fields[1:]
    if len(fields) < 4 or fields[3][0] != 0x30:
        raise ValueError("bad DER encoding (no validity field)")
    times = _der_children(der, fields[3][1], fields[3][2], "validity")
    if len(times) != 2:
        raise ValueError("bad DER encoding (validity is not two times)")
    return _der_time(der, times[0]), _der_time(der, times[1])


def _der_children(data: bytes, start: int, end: int, what: str) -> list[tuple[int, int, int]]:
    """(tag, content start, content end) of each DER element in data[start:end]."""
    out = []
    at = start
    while at < end:
        if at + 2 > end:
            raise ValueError(f"bad DER encoding (truncated {what})")
        tag, length = data[at], data[at + 1]
        at += 2
        if length & 0x80:
            count = length & 0x7F
            if not 1 <= count <= 4 or at + count > end:
                raise ValueError(f"bad DER encoding (length of {what})")
            length = int.from_bytes(data[at:at + count], "big")
            at += count
        if at + length > end:
            raise ValueError(f"bad DER encoding (truncated {what})")
        out.append((tag, at, at + length))
        at += length
    if not out:
        raise ValueError(f"bad DER encoding (empty {what})")
    return out


def _der_time(data: bytes, element: tuple[int, int, int]) -> datetime.datetime:
    """A UTCTime or GeneralizedTime element as an aware UTC datetime."""
    tag, start, end = element
    text = data[start:end].decode("ascii", errors="replace")
    try:
        if tag == 0x17:  # UTCTime YYMMDDHHMMSSZ: 50-99 are 19xx
            parsed = datetime.datetime.strptime(text, "%y%m%d%H%M%SZ")
            if parsed.year >= 2050:
                parsed = parsed.replace(year=parsed.year - 100)
        elif tag == 0x18:  # GeneralizedTime YYYYMMDDHHMMSSZ
            parsed = datetime.datetime.strptime(text, "%Y%m%d%H%M%SZ")
        else:
            raise ValueError
    except ValueError:
        raise ValueError(f"bad DER encoding (validity time {text!r})") from None
    return parsed.replace(tzinfo=datetime.timezone.utc)
