"""What a Linux shared library exports, read from its ELF file without loading it.

`cosim.fmu.archive` holds an FMU's binary for this platform against what fmpy
will bind when it loads it (every `fmi2...`/`fmi3...` function of its class for
the interface), so that a library that is not one, or lacks a function, is named
before the run with the scenario's field, instead of failing at instantiation
with a temporary path. Loading the library to ask would run its code: the check
reads the ELF dynamic symbol table instead (64-bit little-endian files, the
Linux platforms FMI names).
"""

from __future__ import annotations

import platform
import struct

ELF_MAGIC = b"\x7fELF"
SHT_DYNSYM = 11
SHN_UNDEF = 0
MACHINES = {62: "x86_64", 183: "aarch64"}  # e_machine of the platforms FMI names on Linux

_HEADER = struct.Struct("<16sHHIQQQIHHHHHH")  # Elf64_Ehdr
_SECTION = struct.Struct("<IIQQQQIIQQ")  # Elf64_Shdr
_SYMBOL = struct.Struct("<IBBHQQ")  # Elf64_Sym


class NotASharedLibrary(ValueError):
    """The bytes are not a 64-bit little-endian ELF file for this machine; the message says why."""


def exported_names(data: bytes) -> set[str] | None:
    """The symbol names a shared library defines in its dynamic symbol table.

    Args:
        data: the library file's bytes.
    Returns:
        the defined names; None when the file has no dynamic symbol table to read.
    Raises:
        NotASharedLibrary: not an ELF file, not 64-bit little-endian, built for another
            machine than this one, or cut short.
    """
    if data[:4] != ELF_MAGIC:
        raise NotASharedLibrary("not a shared library (not an ELF file)")
    if len(data) < _HEADER.size or data[4] != 2 or data[5] != 1:
        raise NotASharedLibrary("not a 64-bit little-endian ELF file")
    header = _HEADER.unpack_from(data)
    machine, section_offset, section_size, sections = header[2], header[6], header[11], header[12]
    built_for = MACHINES.get(machine, f"machine {machine}")
    if built_for != platform.machine():
        raise NotASharedLibrary(f"built for {built_for}, this machine is {platform.machine()}")
    try:
        table = [_SECTION.unpack_from(data, section_offset + i * section_size)
                 for i in range(sections)]
        for _, kind, _, _, offset, size, link, _, _, entry in table:
            if kind == SHT_DYNSYM:
                return _defined(data, offset, size, entry or _SYMBOL.size, table[link])
    except (struct.error, IndexError):
        raise NotASharedLibrary("a truncated ELF file") from None
    return None


def _defined(data: bytes, offset: int, size: int, entry: int, strings: tuple) -> set[str]:
    """The names of the defined symbols of one symbol table section."""
    names_at = strings[4]
    found = set()
    for at in range(offset + entry, offset + size, entry):  # entry 0 is the null symbol
        name, _, _, section, _, _ = _SYMBOL.unpack_from(data, at)
        if section != SHN_UNDEF and name:
            end = data.index(b"\0", names_at + name)
            found.add(data[names_at + name:end].decode("ascii", "replace"))
    return found
