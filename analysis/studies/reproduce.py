"""``dfwb paper``: run the paper's scenes and write the report.

The scenes (``scenes/figNN_*.toml``) run through :mod:`dfwb.studies.runner`,
which draws each figure with :class:`dfwb.studies.paper.Paper`; this module
only orders the scenes, collects the figures' sections and writes
``report.md``.
"""

import contextlib
import re
import time
from pathlib import Path

from dfwb.base.files import read_bytes, write_atomic
from dfwb.plants.closed_forms import validity_frequencies
from dfwb.studies.cache import open_cache
from dfwb.studies.drawing import Drawing
from dfwb.studies.executor import Executor
from dfwb.studies.runner import begin_scene, phase_times
from dfwb.studies.scene import EPS_FIG8, EPS_FIG9, FRICTION_F, load_scene, shipped_scenes

__all__ = ["run_paper", "paper_scenes", "write_report", "timing_line"]

REPORT = "report.md"
MAX_REPORT = 1 << 20  # bytes of an earlier report read back for its computing time
_COMPUTED_IN = re.compile(r"^Computed in ([0-9]{1,9}(?:\.[0-9]{1,6})?) s", re.MULTILINE)


def timing_line(seconds, computed, earlier=None):
    """The report's line on time: that of the run that computed, and this run's if it only read.

    ``seconds`` is this run's time, ``computed`` the DF points it computed,
    ``earlier`` the computing time an earlier report in the same folder gave
    (None if unknown). A run from the cache never passes for the computing run.

    >>> timing_line(51.04, 1749)
    'Computed in 51.0 s (1749 DF points computed, the rest from the cache or shared between scenes).'
    >>> timing_line(0.11, 0, earlier=51.0)
    'Computed in 51.0 s; this run (from the cache) 0.1 s.'
    >>> timing_line(0.8, 0)
    'This run: 0.8 s, every result from the cache (computed by an earlier run; `--no-cache` recomputes).'
    """
    if computed:
        return (f"Computed in {seconds:.1f} s ({computed} DF point{'s' if computed != 1 else ''} computed, the rest "
                "from the cache or shared between scenes).")
    if earlier is not None:
        return f"Computed in {earlier:.1f} s; this run (from the cache) {seconds:.1f} s."
    return (f"This run: {seconds:.1f} s, every result from the cache (computed by an earlier run; "
            "`--no-cache` recomputes).")


def earlier_seconds(out_dir):
    """The computing time of the report already in ``out_dir``, or None (no report, a link, unreadable)."""
    path = Path(out_dir) / REPORT
    try:
        if path.is_symlink():
            return None
        found = _COMPUTED_IN.search(read_bytes(path, MAX_REPORT, "report").decode("utf-8", "replace"))
    except (OSError, ValueError):
        return None
    return float(found.group(1)) if found else None


def write_report(out_dir, sections, seconds, computed=None, earlier=None):
    """report.md: each figure with what the data say, then the validity frequencies (a table of one row per F).

    ``computed``: the DF points this run computed (None: unknown, taken as a computing run);
    ``earlier``: the computing time of an earlier report in this folder (:func:`timing_line`)."""
    out_dir = Path(out_dir)
    eps_values = sorted(set(EPS_FIG8 + EPS_FIG9))
    rows = ["| F [N] | " + " | ".join(f"w_C, eps = {eps:g}" for eps in eps_values) + " | w_J | w_L |",
            "|---" * (len(eps_values) + 3) + "|"]
    for F in FRICTION_F:
        w = {eps: validity_frequencies(F, eps=eps) for eps in eps_values}
        rows.append(f"| {F:g} | " + " | ".join(f"{w[eps]['w_C']:.3g}" for eps in eps_values)
                    + f" | {w[eps_values[0]]['w_J']:.3g} | {w[eps_values[0]]['w_L']:.3g} |")
    if computed is None:
        timing = f"Computed in {seconds:.1f} s."
    else:
        timing = timing_line(seconds, computed, earlier)
    text = ["# The paper, reproduced", "",
            "Barbosa, Machado and Ferreira, *Describing function analysis of mechanical systems with nonlinear "
            "friction and backlash phenomena* (IFAC 2003), recomputed by dfwb with exact event-driven FMUs "
            "(friction: exact stick, CVS model; Karnopp's band shown on Fig. 4). Convention: input F cos(w t) "
            "from rest, N = X1 / F of the periodic steady state (docs/models.md).", "",
            f"{timing} From the scenes `scenes/fig*.toml`. Data, figures and a summary of each "
            "scene: `<scene>/results.csv`, `results.json`, `summary.md`. The validity frequencies of the dynamic "
            "backlash are tabled at the end.", ""]
    for title, png, body in sections:
        text += [f"## {title}", "", f"![{title}]({png.relative_to(out_dir).as_posix()})", "", body, ""]
    text += ["## Validity frequencies of the dynamic backlash (M2 = 1 kg, h = 0.1 m)", "",
             "w_C = [(2F/(M2 h))^2 (1 - eps)^5]^(1/4) < w < w_L = 2 (F/(M2 h))^(1/2), jump near "
             "w_J = (F/(M2 h))^(1/2), in rad/s (w_J and w_L do not depend on eps):", ""] + rows + [""]
    path = out_dir / REPORT
    write_atomic(path, "\n".join(text))
    return path


def paper_scenes():
    """(path, Scene) of the paper's figures: those that record harmonics first (their points then serve
    the DF-only scenes from the cache), then in figure order."""

    scenes = [(path, load_scene(path)) for path in shipped_scenes("fig")]
    return sorted(scenes, key=lambda item: (not item[1].needs_harmonics, item[0].name))


def run_paper(out_dir="out/paper", jobs=None, fmu_dir=None, progress=True, report=print, cache=True,
              dask=None):
    """Run every paper scene into ``out_dir/<scene>/`` and write ``out_dir/report.md``."""

    started = time.perf_counter()
    out_dir = Path(out_dir)
    earlier = earlier_seconds(out_dir)  # before anything is rewritten: a rerun keeps the computing run's time
    sections = []
    computed = 0
    phases = {}
    runs = []
    drawing = Drawing(jobs) if jobs != 1 else None  # each scene's figure drawn while the next scene computes
    cache = open_cache(cache)  # one for all the scenes: its entries are written in the background meanwhile
    executor = Executor(jobs, dask)  # one for all the scenes: a pool, if any, starts once
    with cache.writing(), drawing or contextlib.nullcontext(), executor:
        try:
            for path, scene in paper_scenes():
                runs.append(begin_scene(scene, out_dir / path.stem, jobs, dask, cache, fmu_dir, progress, drawing,
                                        executor))
            outcomes = [run.finish() for run in runs]
        finally:
            for run in runs:
                run.close()
    for outcome in outcomes:
        sections += outcome.sections
        computed += outcome.computed
        for name, value in outcome.phases.items():
            phases[name] = phases.get(name, 0.0) + value
    sections.sort(key=lambda section: section[1].name)  # figure order
    seconds = time.perf_counter() - started
    path = write_report(out_dir, sections, seconds, computed, earlier)
    report(f"{path} and {len(sections)} figures written in {seconds:.1f} s"
           + ("" if computed else " (from the cache)") + (f": {phase_times(phases)}" if phases else ""))
    return path
