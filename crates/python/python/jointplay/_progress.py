"""The progress bar of long computations: tqdm (``tqdm.auto``, a widget in a notebook) when it
is installed, otherwise one line on standard error rewritten in place."""

import sys


class Bar:
    """A bar over the fraction done (0 to 1) with a short message, drawn by the extension."""

    def __init__(self, label: str) -> None:
        self._label = label
        self._tqdm = None
        try:
            from tqdm.auto import tqdm
        except ImportError:
            tqdm = None
        if tqdm is not None:
            self._tqdm = tqdm(total=1000, desc=label, leave=False,
                              bar_format="{desc} {percentage:3.0f}%|{bar}| "
                                         "[{elapsed}<{remaining}]")
        self._last = ""

    def update(self, fraction: float, message: str) -> None:
        n = int(max(0.0, min(1.0, fraction)) * 1000)
        if self._tqdm is not None:
            self._tqdm.n = n
            desc = f"{self._label}: {message}" if message else self._label
            self._tqdm.set_description_str(desc, refresh=False)
            self._tqdm.refresh()
            return
        line = f"\r{self._label}: {n / 10:5.1f}% {message}"
        if line != self._last:
            sys.stderr.write(line)
            sys.stderr.flush()
            self._last = line

    def close(self) -> None:
        if self._tqdm is not None:
            self._tqdm.close()
        elif self._last:
            sys.stderr.write("\r" + " " * (len(self._last) - 1) + "\r")
            sys.stderr.flush()
