"""Whole calibration studies: a TOML study file and the staged, cached pipeline that runs it.

:func:`load_study` reads and validates a study file (:mod:`podkrig.study.schema`, against the
declarations of :mod:`podkrig.study.settings`);
:func:`run_study` runs its stages — offline FE snapshots, surrogate, held-out validation, the
calibration (:func:`podkrig.online.calibrate.calibrate`: inversion, FE check, region of
equivalence, RVC), sensitivity (and model diagnosis) — caching each by a hash of its
inputs (:mod:`podkrig.study.pipeline`), and writes one HTML report.

Example
-------
>>> from podkrig.study import load_study, run_study
>>> study = load_study("examples/diagonal_compression.toml")
>>> result = run_study(study, "out/demo")       # the demo, about a minute  # doctest: +SKIP
>>> result.calibration.region.intervals["kN_bj"]                           # doctest: +SKIP
(52.40..., 159.27...)
"""

from podkrig.study.pipeline import Progress, StageRecord, StudyResult, run_study
from podkrig.study.schema import Study, StudyError, load_study
from podkrig.study.toml_lines import key_lines

__all__ = ["Progress", "StageRecord", "Study", "StudyError", "StudyResult", "key_lines", "load_study", "run_study"]
