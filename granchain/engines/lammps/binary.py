"""A reader of LAMMPS binary ``dump custom`` files (format revision 2): the frames'
steps and columns, from a memory map of the file, in blocks of samples."""
from __future__ import annotations

import os
import struct
from pathlib import Path

import numpy as np

from ...errors import GranchainError

_BIN_MAGIC = b"DUMPCUSTOM"


def read_binary_dump(path: Path, columns, natoms: int, max_frames: int, what: str, *,
                     consume=None, block: int = 64):
    """Frames of a LAMMPS binary ``dump custom`` file (format revision 2, this machine's
    byte order, rows sorted by id): ``(step (S,) int64, {column: (S, natoms) float64})``.

    Each frame: a header (magic string, endianness, revision, step, atom count, box,
    columns per atom, unit style, time flag, column names, number of chunks) and one
    chunk per writing rank (its count of doubles, then the doubles, one row per atom).
    Checks the atom count and column names against ``columns``/``natoms`` and that there
    are at most ``max_frames``; ``what`` names the file in the one-line errors.

    With ``consume``, the columns are handed over in blocks of ``block`` samples instead,
    ``consume(first_sample, {column: (k, natoms)}, frames)`` (``frames``: an upper bound
    on the number of samples, known from the first frame), and the returned dict is
    empty. When every frame has the first one's header (but its step) and chunk sizes,
    as LAMMPS writes them sorted by id on any number of ranks, the doubles are copied
    block by block from strided views of the file; otherwise frame by frame.
    """
    import mmap

    path = Path(path)
    columns = tuple(columns)
    try:
        fh = open(path, "rb")
    except OSError:
        fh = None
    if fh is None or os.fstat(fh.fileno()).st_size == 0:
        if fh is not None:
            fh.close()
        raise GranchainError(f"{what} is missing or empty: the run wrote no output (see "
                             "log.lammps next to it)")
    with fh:     # MAP_POPULATE: the file's pages mapped in one go, not fault by fault
        mm = mmap.mmap(fh.fileno(), 0, flags=mmap.MAP_SHARED | getattr(mmap, "MAP_POPULATE", 0),
                       prot=mmap.PROT_READ)
    try:
        layout = _frame_layout(mm, columns, natoms, max_frames, what)
        if layout is not None:
            return _read_regular(mm, columns, natoms, layout, consume, block)
        return _read_frames(mm, columns, natoms, max_frames, what, consume, block)
    except (struct.error, ValueError, EOFError, IndexError) as exc:
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise GranchainError(f"{what} is truncated or unreadable: {msg}") from None
    finally:
        try:
            mm.close()
        except BufferError:                           # a view still alive: closed by GC
            pass


def _frame_header(mm, off: int, columns, natoms: int, s: int, what: str):
    """Parse the header of the frame at ``off``: (step, number of chunks, offset of the
    first chunk, offset of the step field)."""
    mlen, = struct.unpack_from("<q", mm, off)
    mlen = -mlen
    magic = mm[off + 8:off + 8 + mlen]
    off += 8 + mlen
    endian, rev = struct.unpack_from("=ii", mm, off)
    step_at = off + 8
    step, nat, tric = struct.unpack_from("=qqi", mm, step_at)
    off += 28 + 24 + 48 + (24 if tric else 0)          # ..., boundary 6i, box 6d (+3d)
    if magic != _BIN_MAGIC or endian != 1 or rev != 2:
        raise GranchainError(f"{what} is not a LAMMPS binary dump custom file of revision 2 "
                             f"in this byte order (magic {magic!r}, endian {endian}, "
                             f"revision {rev})")
    size_one, ulen = struct.unpack_from("=ii", mm, off)
    off += 8 + ulen                                    # unit style (its name if given)
    off += 1 + (8 if mm[off] else 0)                   # time flag (and time)
    clen, = struct.unpack_from("=i", mm, off)
    cols = mm[off + 4:off + 4 + clen]
    off += 4 + clen
    nchunk, = struct.unpack_from("=i", mm, off)
    off += 4
    names = " ".join(columns).encode()
    if nat != natoms or size_one != len(columns) or cols != names:
        raise GranchainError(f"{what} does not match the deck: frame {s} has {nat} atoms x "
                             f"columns {cols.decode(errors='replace')!r}; expected {natoms} x "
                             f"{names.decode()!r}")
    return step, nchunk, off, step_at


def _frame_layout(mm, columns, natoms: int, max_frames: int, what: str):
    """(steps, chunks [(offset, rows)], frame size) if every frame repeats the first
    one's layout, else None."""
    size = len(mm)
    ncol = len(columns)
    _, nchunk, off, step_at = _frame_header(mm, 0, columns, natoms, 0, what)
    chunks, rows_total = [], 0
    for _ in range(nchunk):
        m, = struct.unpack_from("=i", mm, off)
        if m % ncol or rows_total + m // ncol > natoms:
            return None
        chunks.append((off, off + 4, m // ncol))
        rows_total += m // ncol
        off += 4 + 8 * m
    fb = off
    if rows_total != natoms or size % fb or size // fb > max_frames:
        return None
    S = size // fb
    frames = np.ndarray((S, fb), np.uint8, buffer=mm)
    same = np.ones(fb, dtype=bool)                     # bytes every frame repeats:
    same[chunks[0][1] if chunks else fb:] = False      # not the doubles ...
    for at, _, rows in chunks:
        same[at:at + 4] = True                         # ... but the chunk sizes
    same[step_at:step_at + 8] = False                  # ... nor the step
    idx = np.flatnonzero(same)
    ok = bool(np.all(frames[:, idx] == frames[0, idx]))
    steps = np.ndarray((S,), np.int64, buffer=mm, offset=step_at, strides=(fb,)).copy()
    del frames
    if not ok:
        return None
    return steps, [(data, rows) for _, data, rows in chunks], fb


def _read_regular(mm, columns, natoms: int, layout, consume, block: int):
    steps, chunks, fb = layout
    S, ncol = len(steps), len(columns)
    full = {} if consume else {c: np.empty((S, natoms)) for c in columns}
    buf = {c: np.empty((min(block, S), natoms)) for c in columns} if consume else None
    for lo in range(0, S, block):
        hi = min(S, lo + block)
        dst = {c: buf[c][:hi - lo] for c in columns} if consume else \
            {c: full[c][lo:hi] for c in columns}
        r = 0
        for data, rows in chunks:
            view = np.ndarray((hi - lo, rows, ncol), np.float64, buffer=mm,
                              offset=data + lo * fb, strides=(fb, 8 * ncol, 8))
            for j, c in enumerate(columns):
                dst[c][:, r:r + rows] = view[:, :, j]
            del view
            r += rows
        if consume:
            consume(lo, dst, S)
    return steps, full


def _read_frames(mm, columns, natoms: int, max_frames: int, what: str, consume, block: int):
    size, ncol = len(mm), len(columns)
    out, steps, off, lo = None, [], 0, 0
    while off < size:
        s = len(steps)
        start = off
        step, nchunk, off, _ = _frame_header(mm, off, columns, natoms, s, what)
        if s == max_frames:
            raise GranchainError(f"{what} does not match the deck: more than {max_frames} "
                                 "samples")
        if out is None:   # every frame has the first one's size (header + chunks)
            frames = min(max_frames, size // (off - start + nchunk * 4 + 8 * natoms * ncol) + 1)
            out = {c: np.empty((min(block, frames) if consume else frames, natoms))
                   for c in columns}
        row_s = s - lo if consume else s
        row = 0
        for _ in range(nchunk):
            m, = struct.unpack_from("=i", mm, off)
            off += 4
            if m % ncol or row + m // ncol > natoms or off + 8 * m > size:
                raise EOFError(f"frame {s} (step {step}) ends early")
            a = np.frombuffer(mm, np.float64, m, off).reshape(-1, ncol)
            for j, c in enumerate(columns):
                out[c][row_s, row:row + len(a)] = a[:, j]
            del a
            row += m // ncol
            off += 8 * m
        if row != natoms:
            raise EOFError(f"frame {s} (step {step}) holds {row} of {natoms} atoms")
        steps.append(step)
        if consume and (row_s + 1 == len(out[columns[0]]) or off >= size):
            consume(lo, {c: a[:row_s + 1] for c, a in out.items()}, frames)
            lo = s + 1
    S = len(steps)
    full = {} if consume else {c: a[:S] for c, a in (out or {}).items()}
    return np.array(steps, dtype=np.int64), full
