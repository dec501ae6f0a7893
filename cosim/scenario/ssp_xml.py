"""The files of an SSP package and their XML: reading, locating, checking against the schema.

An SSP package is a zip archive (`.ssp`) holding `SystemStructure.ssd` and its
resources (FMUs, `.ssv` parameter sets, `.ssm` parameter mappings); a bare
`.ssd` file with its resources in its folder is read the same way. SSP 1.0
and 2.0 share the XML namespaces (`http://ssp-standard.org/SSP1/...`) and
differ in the `version` attribute and in a few elements (2.0 adds the FMI 3
types Float64, Int32, ..., clocks, array dimensions).

The XML is read with lxml, which keeps each element's line (every message
names the file inside the package and the line) and validates against XSD:
SSP 1.0 files are checked against the SSP 1.0 schemas that fmpy installs
(`fmpy/ssp/schema/`); no SSP 2.0 schema ships with fmpy, so 2.0 files get the
reader's own structural checks only (`cosim.scenario.ssp`). Entities and
network access are off (no XXE). FMUs inside an `.ssp` are extracted once into
the per-user cache, one folder per hash of the archive.
"""

from __future__ import annotations

import hashlib
import os
import posixpath
import zipfile
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any
from urllib.parse import unquote, urlparse

from lxml import etree

from cosim.errors import Problem, ScenarioError

SSP1 = "http://ssp-standard.org/SSP1/"
NS = {
    "ssd": SSP1 + "SystemStructureDescription",
    "ssc": SSP1 + "SystemStructureCommon",
    "ssv": SSP1 + "SystemStructureParameterValues",
    "ssm": SSP1 + "SystemStructureParameterMapping",
    "ssb": SSP1 + "SystemStructureSignalDictionary",
}
SSD_MEMBER = "SystemStructure.ssd"
SCHEMAS = {"ssd": "SystemStructureDescription.xsd", "ssv": "SystemStructureParameterValues.xsd",
           "ssm": "SystemStructureParameterMapping.xsd"}
VERSIONS = ("1.0", "2.0")
_PARSER = etree.XMLParser(resolve_entities=False, no_network=True, remove_comments=True)


def q(tag: str) -> str:
    """'ssd:Component' -> '{namespace}Component' (lxml's qualified name)."""
    prefix, _, local = tag.partition(":")
    return f"{{{NS[prefix]}}}{local}"


def short(element: Any) -> str:
    """An element's tag as 'ssd:Component' (prefix by namespace), for messages."""
    qname = etree.QName(element)
    prefix = next((p for p, uri in NS.items() if uri == qname.namespace), None)
    return f"{prefix}:{qname.localname}" if prefix else qname.localname


@dataclass
class Located:
    """A problem found in one member of the package, at an XML element's line."""

    member: str
    line: int | None
    what: str
    message: str


class SspPackage:
    """An .ssp archive or a bare .ssd file, and the problems found reading it.

    Args:
        path: the .ssp (zip) or .ssd file.
    """

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self.problems: list[Located] = []
        self._zip: zipfile.ZipFile | None = None
        if self.path.suffix.lower() == ".ssd":
            return
        if not self.path.is_file():
            raise ScenarioError(self.path, [Problem("", None, "SSP file not found")])
        if not zipfile.is_zipfile(self.path):
            raise ScenarioError(self.path, [Problem("", None, (
                "not an SSP package (an .ssp is a zip archive holding SystemStructure.ssd)"))])
        self._zip = zipfile.ZipFile(self.path)

    @property
    def ssd_member(self) -> str:
        """The member name of the system structure (the file's own name for a bare .ssd)."""
        return self.path.name if self._zip is None else SSD_MEMBER

    def error(self, member: str, element: Any, what: str, message: str) -> None:
        """Record a problem at an element (None: the member as a whole)."""
        line = getattr(element, "sourceline", None)
        self.problems.append(Located(member, line, what, message))

    def raise_problems(self) -> None:
        """Raise one ScenarioError listing every recorded problem, if any."""
        if self.problems:
            by_member = sorted(self.problems, key=lambda p: (p.member, p.line or 0))
            raise ScenarioError(self.path, [Problem(
                p.member + (f":{p.line}" if p.line else "") + (f": {p.what}" if p.what else ""),
                None, p.message) for p in by_member])

    # ---- members ------------------------------------------------------------------------
    def exists(self, member: str) -> bool:
        """True if the package holds `member` (a normalised relative path)."""
        if self._zip is None:
            return (self.path.parent / member).is_file()
        return member in self._zip.namelist()

    def read(self, member: str) -> bytes:
        """The bytes of a member (it must exist)."""
        if self._zip is None:
            return (self.path.parent / member).read_bytes()
        return self._zip.read(member)

    def resolve(self, uri: str, base_member: str | None = None) -> str | None:
        """A source URI as a member name, relative to `base_member`'s folder (None: the root).

        Returns None for URIs that point outside the package (absolute paths,
        other schemes, or '..' above the root).
        """
        parsed = urlparse(uri)
        if parsed.scheme not in ("", "file") or parsed.netloc or not parsed.path:
            return None
        path = unquote(parsed.path)
        if path.startswith("/"):
            return None
        folder = posixpath.dirname(base_member) if base_member else ""
        member = posixpath.normpath(posixpath.join(folder, path))
        return None if member.startswith("..") else member

    def fmu_file(self, member: str) -> Path:
        """A path on disk to an FMU member: itself for a bare .ssd, else extracted into the cache."""
        if self._zip is None:
            return (self.path.parent / member).resolve()
        digest = hashlib.sha256(self.path.read_bytes()).hexdigest()[:20]
        target = _cache_root() / "ssp" / digest / member
        if target.suffix.lower() != ".fmu":
            target = target.with_name(target.name + ".fmu")
        if not target.is_file():
            target.parent.mkdir(parents=True, exist_ok=True)
            partial = target.with_name(f".{target.name}.{os.getpid()}")
            partial.write_bytes(self._zip.read(member))
            partial.replace(target)  # atomic: concurrent runs never see half a file
        return target

    # ---- XML ----------------------------------------------------------------------------
    def xml(self, member: str, kind: str, version: str | None = None) -> Any:
        """The root element of an XML member, or None after recording why not.

        Args:
            member: the member name.
            kind: "ssd", "ssv" or "ssm": the expected root element and schema.
            version: when "1.0", also validate against fmpy's SSP 1.0 schema.
        """
        try:
            root = etree.fromstring(self.read(member), _PARSER)
        except etree.XMLSyntaxError as exc:
            self.problems.append(Located(member, exc.lineno, "", f"not well-formed XML: {exc.msg}"))
            return None
        expected = {"ssd": "ssd:SystemStructureDescription", "ssv": "ssv:ParameterSet",
                    "ssm": "ssm:ParameterMapping"}[kind]
        if root.tag != q(expected):
            self.error(member, root, short(root), f"the root element must be {expected} "
                       f"(namespace {NS[kind]}), not {root.tag}")
            return None
        if (version or root.get("version")) == "1.0":
            self._validate(member, root, kind)
        return root

    def _validate(self, member: str, root: Any, kind: str) -> None:
        """Record the SSP 1.0 schema violations of a document."""
        schema = _schema(SCHEMAS[kind])
        if schema is None or schema.validate(root):
            return
        for entry in schema.error_log:
            self.problems.append(Located(member, entry.line, "schema",
                                         entry.message.replace("{" + SSP1, "{…/")))


@lru_cache(maxsize=None)
def _schema(name: str) -> Any:
    """fmpy's SSP 1.0 XSD of that name, compiled; None when fmpy has none."""
    try:
        from importlib.resources import files

        path = Path(str(files("fmpy.ssp") / "schema" / name))
    except (ImportError, ModuleNotFoundError, TypeError):
        return None
    return etree.XMLSchema(etree.parse(str(path))) if path.is_file() else None


def _cache_root() -> Path:
    """$COSIM_CACHE_DIR, else the user cache folder of "cosim" (as cosim.fmu.cache)."""
    env = os.environ.get("COSIM_CACHE_DIR")
    if env:
        return Path(env)
    import platformdirs

    return Path(platformdirs.user_cache_dir("cosim", appauthor=False))
