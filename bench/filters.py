#!/usr/bin/env python3
"""How small can a run file's samples get without losing a bit?

  python3 bench/filters.py RUN.h5

Reads every floating-point time series of a jointplay run file and compresses it, chunk by
chunk (the file's 2048-sample chunks), in the ways a lossless HDF5 filter chain could:

- `rows`: the file's own chain, shuffle then deflate level 4, on chunks of whole samples
  (the x, y, z columns of a dataset interleaved), what jointplay writes;
- `columns`: the same on one column at a time (a chunk shape of (2048, 1));
- `columns-9`: the same at deflate level 9;
- `xor-delta`: each value XORed with the one before it in its column, then shuffle and deflate 4
  (the transform of time-series databases' float compression; no standard HDF5 filter does it);
- `delta-1`, `delta-2`, `delta-3`: the bit pattern of each value, read as a 64-bit integer, less
  the one a polynomial through the 1, 2 or 3 samples before it predicts (integer differences of
  order 1 to 3, the Lorenzo-style prediction of floating-point compressors such as fpzip), mapped
  to unsigned (zigzag), then shuffle and deflate 4 (no standard HDF5 filter does this either).

It prints the raw size of the samples and, per method, the compressed size and the ratio raw /
compressed. Sizes count the samples only (no HDF5 metadata).
"""
import sys
import zlib

import h5py
import numpy as np

CHUNK = 2048


def shuffle(a):
    """The HDF5 shuffle filter: byte k of every element, for k = 0 .. itemsize - 1."""
    b = np.ascontiguousarray(a).view(np.uint8).reshape(-1, a.dtype.itemsize)
    return b.T.tobytes()


def main():
    sizes = {"raw": 0, "rows": 0, "columns": 0, "columns-9": 0, "xor-delta": 0,
             "delta-1": 0, "delta-2": 0, "delta-3": 0}

    def visit(_name, obj):
        if not isinstance(obj, h5py.Dataset) or obj.dtype != np.float64:
            return
        if obj.ndim == 0 or obj.shape[0] < CHUNK // 8:
            return
        x = obj[()]
        if x.ndim == 1:
            x = x[:, None]
        for s in range(0, x.shape[0], CHUNK):
            c = np.ascontiguousarray(x[s:s + CHUNK])
            sizes["raw"] += c.nbytes
            sizes["rows"] += len(zlib.compress(shuffle(c), 4))
            for j in range(c.shape[1]):
                col = np.ascontiguousarray(c[:, j])
                shuffled = shuffle(col)
                sizes["columns"] += len(zlib.compress(shuffled, 4))
                sizes["columns-9"] += len(zlib.compress(shuffled, 9))
                u = col.view(np.uint64)
                d = u.copy()
                d[1:] ^= u[:-1]
                sizes["xor-delta"] += len(zlib.compress(shuffle(d), 4))
                # Wrapping integer differences, applied in place: after order k, r[0] is the first
                # value and r[j], j < k, its j-th difference.
                r = col.view(np.int64).copy()
                for order in (1, 2, 3):
                    r[order:] = r[order:] - r[order - 1:-1]
                    z = ((r << np.int64(1)) ^ (r >> np.int64(63))).view(np.uint64)
                    sizes[f"delta-{order}"] += len(zlib.compress(shuffle(z), 4))

    with h5py.File(sys.argv[1], "r") as f:
        f.visititems(visit)
    raw = sizes["raw"]
    print("| method | bytes | raw / compressed |")
    print("|---|---|---|")
    for k, v in sizes.items():
        print(f"| {k} | {v} | {raw / v:.2f} |")


if __name__ == "__main__":
    main()
