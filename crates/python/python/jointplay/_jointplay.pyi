"""Type stubs of the jointplay extension module. All quantities are SI: m, kg, s, rad, N, N m, J."""

from os import PathLike
from typing import Any, Optional, Union

import numpy as np
import numpy.typing as npt

__version__: str

StrPath = Union[str, "PathLike[str]"]

class JointplayError(Exception):
    """An error of jointplay: the message names the file, the field or path, the value and the
    time."""

class Interrupted(KeyboardInterrupt):
    """Ctrl-C stopped a computation cleanly. ``partial`` is what was kept: the ``Run`` up to the
    interruption, or the ``StudyResult`` of a file marked incomplete (a sweep keeps its finished
    values; ``run_study(..., resume=True)`` runs the rest), or None."""

    partial: Optional[Union["Run", "StudyResult"]]

class Scene:
    """A mechanism scene: the TOML tree of a scene file, read and edited by study paths.

    ``scene["joints.S2.clearance.radial_clearance"] = 4e-4`` (m) edits it as a study's ``set``
    does; ``del scene[path]`` as its ``remove``. Paths select array elements by name, position
    or ``*`` and vector components by index (``bodies.ball.velocity.0``). Each edit is checked
    against the scene format at once (``JointplayError`` naming the path); values out of range
    are refused by ``check()`` and ``run()``, naming the field."""

    @staticmethod
    def from_toml(text: str, path: str = "scene.toml") -> Scene:
        """A scene from TOML text; ``path`` names it in messages and gives its default name."""
    def __getitem__(self, path: str) -> Any:
        """The value at ``path`` (a list for a path with ``*``); ``KeyError`` naming the path
        when absent (a field left at its default is not in the scene)."""
    def __setitem__(self, path: str, value: Any) -> None: ...
    def __delitem__(self, path: str) -> None: ...
    def __contains__(self, path: str) -> bool: ...
    @property
    def name(self) -> str:
        """The scene's name (its ``name`` field or the file stem); names its output file."""
    @property
    def path(self) -> str:
        """The file the scene was read from, or the path given to ``from_toml``."""
    def to_toml(self) -> str:
        """The scene as TOML text (the file as read until edited)."""
    def to_dict(self) -> dict[str, Any]:
        """A copy of the scene's tree."""
    def copy(self) -> Scene: ...
    def check(self) -> dict[str, Any]:
        """What ``jointplay check`` prints, as a dict: ``dof``, ``rank``, ``joint_rank``,
        ``redundant_joint_rows``, ``redundant_drives``, ``coordinates``, ``bristle_states`` (the
        LuGre contacts' deflections, 3 each, after the bodies' coordinates in the state), ``bodies`` (mass in kg,
        inertia in kg m^2, the number of ``shapes`` it is drawn with), ``joints``, ``drives`` (period in s), ``assembly`` (residuals in m or
        rad, m/s or rad/s), ``closed_start`` (the clearance joints the start closed as ideal
        joints with their eccentricities in m, whether that moved the start, and how far the
        start assembled without closing them was, in m or rad and m/s or rad/s; None without
        such joints), ``effects``, ``disabled``, ``solver``, ``start_time`` and
        ``end_time`` (s), ``period`` (s), ``output``, ``warnings`` and the printed ``lines``."""
    def run(self, progress: bool = True) -> Run:
        """Simulates the scene from its start to its end time; the GIL is released, a progress
        bar appears after a second. A diverging run returns with ``complete`` False. Ctrl-C
        raises ``Interrupted`` with the run so far in ``partial``."""

def load_scene(path: StrPath) -> Scene:
    """Reads a scene file (TOML); errors name the file and the field."""

class Run:
    """A simulated run. Arrays are read-only numpy views of the run's memory (no copy)."""

    @property
    def time(self) -> npt.NDArray[np.float64]:
        """Sample times (s)."""
    def __getitem__(self, dataset: str) -> npt.NDArray[np.float64]:
        """A dataset of the run file (``bodies/bob/position``): samples x components, or one
        value per sample for a scalar; its unit is ``units[dataset]``."""
    def observable(self, path: str) -> npt.NDArray[np.float64]:
        """One recorded column by its observable path (``bodies.bob.position.x``)."""
    def strobe(
        self, path: str, phase: float = 0.0, period: Optional[float] = None
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """A stroboscopic (Poincare) section: ``(times, values)`` of ``path`` (a dataset or an
        observable path) at ``t0 + phase + k * period`` (s) up to the last sample, ``period``
        the drives' common period by default. The last strobe time is kept where rounding would
        drop it; a strobe time that is not a sample time is a ValueError naming the
        ``output.interval`` that would make it one."""
    @property
    def datasets(self) -> list[str]: ...
    @property
    def units(self) -> dict[str, str]:
        """The SI unit of every dataset (``"m"``, ``"m/s"``, ``"N"``; ``"s"`` for time)."""
    @property
    def columns(self) -> dict[str, list[str]]:
        """The observable path of each column of every dataset."""
    @property
    def name(self) -> str: ...
    @property
    def complete(self) -> bool:
        """True when the run reached its end time."""
    @property
    def stopped(self) -> Optional[dict[str, Any]]:
        """``{"time": s, "message": str, "interrupted": bool}`` when the run stopped early."""
    @property
    def stats(self) -> dict[str, float]:
        """Accepted and rejected steps, right-hand-side evaluations, wall time (s)."""
    @property
    def warnings(self) -> list[str]: ...
    def write(self, out: StrPath = "out") -> str:
        """Writes ``out/<name>.h5`` as ``jointplay run`` does (marked incomplete when the run
        stopped early) and returns its path."""

class H5:
    """An HDF5 file written by jointplay, read on demand."""

    def __init__(self, path: StrPath) -> None: ...
    @property
    def path(self) -> str: ...
    @property
    def datasets(self) -> list[str]:
        """Every dataset's path (``sweep/x``, ``cases/ideal/bodies/platform/position``)."""
    @property
    def attrs(self) -> dict[str, Any]:
        """The root attributes (``complete``, ``units``, ``study``, ...)."""
    def attributes(self, path: str) -> dict[str, Any]:
        """The attributes of a group or dataset."""
    @property
    def units(self) -> dict[str, str]:
        """The SI unit of every dataset that states one."""
    def __getitem__(self, path: str) -> Union[npt.NDArray[np.float64], list[str]]:
        """A dataset: numbers as float64 (flags and counters too), text as a list of str."""
    def __contains__(self, path: str) -> bool: ...

def load(path: StrPath) -> H5:
    """Opens an HDF5 file written by jointplay."""

class StudyResult:
    """What ``run_study`` wrote."""

    kind: str
    """``comparison``, ``analysis`` or ``precision``."""
    file: str
    """The HDF5 file."""
    data: H5
    """The file, loaded on demand (``result["sweep/x"]`` reads from it)."""
    complete: bool
    failed: list[tuple[str, str]]
    table: Optional[str]
    """The comparison or work-precision table (markdown)."""
    table_file: Optional[str]
    figures: list[str]
    warnings: list[str]
    def __getitem__(self, path: str) -> Union[npt.NDArray[np.float64], list[str]]: ...

def run_study(
    source: StrPath,
    out: StrPath = "out",
    threads: Optional[int] = None,
    progress: bool = True,
    resume: bool = False,
    max_jobs: Optional[int] = None,
    plots: bool = False,
    precision: bool = False,
) -> StudyResult:
    """Runs a comparison, analysis (sweep) or work-precision study (``source``: its file or its
    TOML text) as the program does and returns the written file loaded. ``threads``: cases or
    sweep values at once (default every core). ``resume``/``max_jobs``: as ``--resume`` and
    ``--max-jobs`` (sweep values, or a continuation's points). ``plots``: draw the figures. A
    ``[continuation]`` is followed after the analysis, into the same file. A failed case or value raises
    ``JointplayError`` after the file is written. Ctrl-C raises ``Interrupted``."""

def set_figure_style(
    size: tuple[int, int] = (560, 380), scale: float = 1.0, font_scale: float = 1.0
) -> None:
    """How every figure drawn from now on is sized: one panel's (width, height) in px at scale
    1, a resolution factor on every pixel dimension (0.25 to 8), a factor on the fonts (0.5 to
    4); as the program's --figure-size, --figure-scale and --font-scale."""
def set_hdf5_format(version: str) -> None:
    """Sets the HDF5 format of every file written from now on in this process: ``"1.10"`` (the
    default; smaller files, read by HDF5 1.10 and later) or ``"1.8"`` (the oldest format, for
    readers built on HDF5 1.8), as the program's ``--hdf5-format``. The values are the same."""
