"""Opening an HDF5 file for reading so that a damaged file is named as damaged, quickly.

Two ways a reader could hang or lie on a truncated or bit-flipped file are closed here:

* SWMR reading skips HDF5's end-of-file check and retries a metadata block whose checksum fails
  100 times with a growing sleep (it assumes a live writer is half-way through an update), which
  took more than 590 s on a truncated dataset. A file is opened in SWMR mode only when its
  superblock says a writer has it open (a run in progress, or killed); then with
  ``SWMR_READ_ATTEMPTS`` attempts (milliseconds), not 100. Otherwise it is opened plainly
  read-only, and HDF5 checks the end of file itself.
* Before h5py sees the file, its superblock is read here: a file shorter than the end-of-file
  address the superblock records is *truncated*, said in one line.

Every failure is a :class:`UserError` naming the file (exit 2). Superblock layout: HDF5 File
Format Specification version 3.0, §II.A (versions 0-3).
"""

from __future__ import annotations

import ctypes
import functools
import os
import struct
from dataclasses import dataclass
from pathlib import Path

from pipeline.errors import UserError

SIGNATURE = b"\x89HDF\r\n\x1a\n"
SWMR_READ_ATTEMPTS = 8             # HDF5's default for SWMR reads is 100 with exponential sleeps
_WRITE_ACCESS_FLAGS = 0x1 | 0x4    # superblock v3 consistency flags: open for write, SWMR write


@dataclass(frozen=True)
class Superblock:
    offset: int                    # byte offset of the superblock (0 or a power of two >= 512)
    version: int
    base_address: int
    eof_address: int               # relative to base_address
    open_for_write: bool


def first_line(exc: BaseException) -> str:
    return (str(exc).strip().splitlines() or [type(exc).__name__])[0]


def read_superblock(path: Path) -> Superblock:
    """The superblock of ``path``; UserError if there is none (not HDF5) or it is cut short."""
    with open(path, "rb") as handle:
        size = os.fstat(handle.fileno()).st_size
        offset = 0
        while offset + len(SIGNATURE) <= size:
            handle.seek(offset)
            head = handle.read(96)
            if head.startswith(SIGNATURE):
                return _parse_superblock(path, offset, head)
            offset = 512 if offset == 0 else offset * 2
    raise UserError(f"{path}: not a readable HDF5 file (no superblock signature)")


def _parse_superblock(path: Path, offset: int, head: bytes) -> Superblock:
    """Versions 0/1: the size of offsets at byte 13, addresses (base, free space, end of file, ...)
    from byte 24 (28 for version 1); versions 2/3: size of offsets at byte 9, consistency flags at
    11, addresses (base, extension, end of file, ...) from byte 12."""
    version = head[8]
    if version in (0, 1):
        offset_size, addresses_at, open_for_write = head[13], 24 + 4 * version, False
    elif version in (2, 3):
        offset_size, addresses_at = head[9], 12
        open_for_write = version == 3 and bool(head[11] & _WRITE_ACCESS_FLAGS)
    else:
        raise UserError(f"{path}: damaged HDF5 file (unknown superblock version {version})")
    if offset_size not in (2, 4, 8) or len(head) < addresses_at + 3 * offset_size:
        raise UserError(f"{path}: damaged HDF5 file (superblock cut short or corrupt)")
    code = {2: "<H", 4: "<I", 8: "<Q"}[offset_size]
    base, _, eof = (struct.unpack_from(code, head, addresses_at + i * offset_size)[0] for i in range(3))
    return Superblock(offset, version, base, eof, open_for_write)


@functools.cache
def _set_read_attempts():
    """HDF5's ``H5Pset_metadata_read_attempts`` from the library h5py is linked with (h5py does not
    wrap it; dlsym on h5py's own extension module finds its libhdf5)."""
    # imported here, not at the top: ≈0.02 CPU-s on a worker's start-up
    import h5py.h5p

    function = ctypes.CDLL(h5py.h5p.__file__).H5Pset_metadata_read_attempts
    function.argtypes, function.restype = [ctypes.c_int64, ctypes.c_uint], ctypes.c_int
    return function


def open_hdf5(path: Path, what: str = "HDF5 file"):
    """``path`` open read-only as an ``h5py.File``: SWMR (bounded retries) only if a writer has it
    open, else plain (HDF5 checks the end of file). UserError naming the file if it cannot be read,
    is not HDF5, is truncated or its metadata are damaged."""
    # imported here, not at the top: ≈0.02 CPU-s on a worker's start-up
    import h5py

    path = Path(path)
    try:
        superblock = read_superblock(path)
    except OSError as exc:
        raise UserError(f"{path}: cannot read the {what} ({exc.strerror or first_line(exc)})") from None
    size = path.stat().st_size
    if not superblock.open_for_write and superblock.base_address + superblock.eof_address > size:
        raise UserError(f"{path}: damaged {what}: truncated ({size} bytes of "
                        f"{superblock.base_address + superblock.eof_address})")
    fapl = h5py.h5p.create(h5py.h5p.FILE_ACCESS)
    flags = h5py.h5f.ACC_RDONLY
    if superblock.open_for_write:
        _set_read_attempts()(fapl.id, SWMR_READ_ATTEMPTS)
        flags |= h5py.h5f.ACC_SWMR_READ
    try:
        return h5py.File(h5py.h5f.open(os.fsencode(path), flags, fapl=fapl))
    except (OSError, RuntimeError, ValueError) as exc:
        raise UserError(f"{path}: damaged {what} ({first_line(exc)})") from None


def refuse_external_links(handle, what: str = "HDF5 file") -> None:
    """UserError if the open file ``handle`` holds an external link: its data would come from
    another file, which neither the reader's checks nor a provenance hash of this file cover."""
    # imported here, not at the top: ≈0.02 CPU-s on a worker's start-up
    import h5py

    found = []
    handle.visititems_links(lambda name, link: found.append(name) if isinstance(link, h5py.ExternalLink) else None)
    if found:
        raise UserError(f"{handle.filename}: {what} holds an external link ({found[0]}) to another file; "
                        "copy the data into it (h5copy, or h5py's copy)")
