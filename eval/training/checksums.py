"""Checksums that prove a run file holds what its writer wrote.

Two kinds, both SHA-256:

- `content_digest`: of a Python object as a torch file holds it (tensors, arrays, numbers, strings,
  in containers), computed from the values themselves. Checked on the object torch *loaded*, it
  catches what no archive-level CRC can: torch reads its zip archives with its own reader, and a
  damaged central directory can make it return a tensor it never filled.
- A checksum file NAME.sha256 beside a text file NAME (`write_checked`, `read_checked`): lines of
  `DIGEST  NAME` (sha256sum's format), the file's digest first and then that of the version it
  replaced, which the checksum file is written before: a kill between the two writes leaves the
  earlier, whole version, which still verifies. A file without a checksum file beside it (written
  before checksums were kept) reads as unverified, not damaged.
"""

from __future__ import annotations

import hashlib
import math
import pickle
import struct
from pathlib import Path
from typing import Any

from lava_bridge_mj.eval.training.atomic import atomic_write, atomic_write_text

CHECKSUM_SUFFIX = ".sha256"


class DamagedFileError(ValueError):
    """A run file exists but cannot be used: truncated, bit-flipped, edited or not what it should be."""


def content_digest(obj: Any) -> str:
    """SHA-256 of `obj`'s values: each tensor's dtype, shape and bytes (wherever it lives), each numpy
    array's, and every number, string and container around them, in order. Equal for an object and its
    torch.save / torch.load round trip; any changed byte of a value changes it."""
    import torch  # on use: readers of text files never load torch

    digest = hashlib.sha256()

    def feed(tag: bytes, header: Any = "", data: bytes = b"") -> None:
        text = str(header).encode()
        digest.update(b"%s%d:%s%d:" % (tag, len(text), text, len(data)) + data)

    def visit(value: Any) -> None:
        if isinstance(value, torch.Tensor):
            flat = value.detach().to("cpu").contiguous().reshape(-1)
            feed(b"T", (str(value.dtype), tuple(value.shape)), flat.view(torch.uint8).numpy().tobytes())
        elif _is_numpy(value) and not value.dtype.hasobject:
            import numpy as np

            array = np.ascontiguousarray(value)
            feed(b"A", (array.dtype.str, array.shape), array.tobytes())
        elif isinstance(value, dict):
            feed(b"D", len(value))
            for key, item in value.items():
                visit(key)
                visit(item)
        elif isinstance(value, (list, tuple)) or _is_numpy(value):  # an object array: its items
            items = value.tolist() if _is_numpy(value) else value
            feed(b"L" if isinstance(value, list) else b"U", len(items))
            for item in items:
                visit(item)
        elif isinstance(value, (set, frozenset)):  # no order of their own: sorted by their items' digests
            feed(b"E", len(value), "".join(sorted(content_digest(item) for item in value)).encode())
        elif isinstance(value, (str, bytes)):
            feed(b"S" if isinstance(value, str) else b"Y", "",
                 value.encode("utf-8", "surrogatepass") if isinstance(value, str) else value)
        elif value is None or isinstance(value, int):  # bool included: its type name tells it from 0 and 1
            feed(b"I", type(value).__name__, hex(value or 0).encode())
        elif isinstance(value, float):
            feed(b"F", "", _float_bytes(value))
        else:  # any other picklable object: as pickle spells it
            feed(b"P", type(value).__qualname__, pickle.dumps(value, protocol=4))

    visit(obj)
    return digest.hexdigest()


def _is_numpy(value: Any) -> bool:
    return type(value).__module__ == "numpy" and hasattr(value, "dtype")


def _float_bytes(value: float) -> bytes:
    # every NaN alike: its payload bits carry no value and need not survive a pickle round trip
    return b"nan" if math.isnan(value) else struct.pack("<d", value)


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def checksum_file(path: str | Path) -> Path:
    """Where the checksum file of `path` lies: NAME.sha256 beside it."""
    path = Path(path)
    return path.with_name(path.name + CHECKSUM_SUFFIX)


def verdict(path: str | Path, data: bytes) -> bool | None:
    """Whether `data` (the bytes of `path`) is what its writer wrote: True if its checksum file lists
    its digest, False if it lists others, None when there is no checksum file. DamagedFileError naming
    the checksum file when that cannot be read or is not one."""
    sums = checksum_file(path)
    try:
        text = sums.read_text()
    except FileNotFoundError:
        return None
    except (OSError, UnicodeDecodeError) as error:
        raise DamagedFileError(f"{sums} cannot be read ({getattr(error, 'strerror', None) or error})") from None
    digests = [line.split("  ", 1)[0] for line in text.splitlines()]
    if not digests or not all(len(d) == 64 and all(c in "0123456789abcdef" for c in d) for d in digests):
        raise DamagedFileError(f"{sums} is not a checksum file (lines of a SHA-256 digest and a file name)")
    return sha256(data) in digests


def read_checked(path: str | Path) -> bytes:
    """The bytes of `path`, verified against its checksum file where it has one; DamagedFileError naming
    the file when they do not match it (edited or damaged since it was written). OSError as usual."""
    data = Path(path).read_bytes()
    if verdict(path, data) is False:
        raise DamagedFileError(f"{path} does not match its checksum in {checksum_file(path).name}: it was "
                               "changed after it was written (restore it, or train or export its run again)")
    return data


def write_checked(path: str | Path, data: bytes) -> None:
    """Write `data` to `path` atomically with its checksum file, which goes first and lists the digest of
    the version `path` held before too (if that one verified, or had none to verify it)."""
    path = Path(path)
    digests = [sha256(data)]
    try:
        current = path.read_bytes()
        if verdict(path, current) is not False and sha256(current) not in digests:
            digests.append(sha256(current))
    except (FileNotFoundError, DamagedFileError):
        pass  # nothing whole to fall back to: only the new version verifies
    atomic_write_text(checksum_file(path), "".join(f"{digest}  {path.name}\n" for digest in digests))
    atomic_write(path, lambda f: f.write(data))
