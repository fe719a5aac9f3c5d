"""jointplay: nonlinear dynamics of mechanisms whose joints have clearance.

The package is the jointplay program's own Rust code (not a wrapper around the command line):

* ``load_scene(path)`` / ``Scene.from_toml(text)``: a scene, read and edited by the paths of
  studies (``scene["joints.S2.clearance.radial_clearance"] = 4e-4``);
* ``scene.check()``: the compiled summary (degrees of freedom, redundancy, effects) as a dict;
* ``scene.run()``: a ``Run`` whose recorded quantities are numpy arrays with their SI units,
  written to the usual HDF5 file by ``run.write(out)``;
* ``run_study(path_or_text, out=..., threads=..., progress=True)``: comparison, analysis (sweep)
  and work-precision studies, returning the HDF5 file loaded as a ``StudyResult``;
* ``load(path)``: any HDF5 file jointplay writes, dataset by dataset as numpy arrays;
* ``set_hdf5_format("1.8")``: files from then on in the oldest HDF5 format (default ``"1.10"``).
* ``set_figure_style(size=(800, 500), scale=2, font_scale=1.2)``: how figures are sized from
  then on (panel size in px, resolution factor, font factor).

All quantities are SI: m, kg, s, rad, N, N m, J. Errors raise ``JointplayError`` with the
program's message (file, field or path, value, time). Long runs release the GIL and show a
progress bar (tqdm when installed); Ctrl-C stops them cleanly and raises ``Interrupted`` (a
``KeyboardInterrupt``) whose ``partial`` holds what was kept.
"""

from ._jointplay import (
    H5,
    Interrupted,
    JointplayError,
    Run,
    Scene,
    StudyResult,
    __version__,
    load,
    load_scene,
    run_study,
    set_figure_style,
    set_hdf5_format,
)

__all__ = [
    "H5",
    "Interrupted",
    "JointplayError",
    "Run",
    "Scene",
    "StudyResult",
    "__version__",
    "load",
    "load_scene",
    "run_study",
    "set_figure_style",
    "set_hdf5_format",
]
