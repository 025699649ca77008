"""dfwb: a describing-function workbench for friction and backlash, on FMI co-simulation.

The public API, in the style of python-control: functions that return
response objects with a ``.plot()``.

- :func:`describing_function` -- N(F, omega) of a plant over a broadcast grid
  (:class:`DescribingFunctionResponse`);
- :func:`limit_cycles` -- limit cycles of a plant under a controller G(s)
  (:class:`LimitCycleResponse`); :func:`transfer_function` reads a G(s);
- :func:`continuation` -- cycles followed in one parameter, with bifurcations
  (:class:`ContinuationResponse`); :func:`hunting_map` -- which settings of two
  parameters make the machine hunt, truth and DF (:class:`HuntingMapResponse`);
  :func:`limit_cycle_margin` -- the gain factors k for which k G hunts (:class:`MarginResponse`);
  :func:`tune` -- the fastest controller, with its compensators, that does not hunt (:class:`TuneResponse`);
- :func:`run_scene`, :func:`sweep` and :func:`grid` -- studies written to a folder;
- :func:`plant`, :func:`names`, :class:`Plant`, :func:`register` -- the plant registry
  (:mod:`dfwb.plants`, whose ``PLANTS`` maps each name to its entry);
- :func:`fmu_plant` -- your own FMU (FMI 2.0/3.0, model exchange or co-simulation) as the
  plant of :func:`describing_function` and the rest (:class:`FMUPlant`);
- :class:`DfwbError` -- the base of every error a user can act on.

A DF point has one shape everywhere, its record (a flat dict: ``F`` [N],
``omega`` [rad/s], ``N_re``/``N_im`` [m/N], ``minus_inv_N_re``/``_im``
[N/m], ``harmonics`` [m], ...): ``results.json`` holds records,
``results.csv`` flattened records (units in the column names), and
``DescribingFunctionResponse.points`` lists them.

Examples
--------
>>> import dfwb
>>> dfwb.names()[:3]
('friction', 'backlash', 'static-backlash')
>>> response = dfwb.describing_function("friction", F=[10.0, 20.0], omega=1.0)
>>> response.N.shape, response.periodic.tolist()
((2,), [True, True])
"""

__version__ = "0.1.0"

import importlib
from typing import TYPE_CHECKING

# Where each public name lives. They load on first use (PEP 562), so that ``dfwb --help``
# and a worker process do not pay for numpy, matplotlib and python-control up front.
_PUBLIC = {
    "describing_function": "dfwb.api.functions", "limit_cycles": "dfwb.api.functions",
    "continuation": "dfwb.api.functions", "ContinuationResponse": "dfwb.studies.responses",
    "hunting_map": "dfwb.api.functions", "HuntingMapResponse": "dfwb.studies.responses",
    "limit_cycle_margin": "dfwb.api.functions", "MarginResponse": "dfwb.studies.responses",
    "tune": "dfwb.api.functions", "TuneResponse": "dfwb.studies.responses",
    "transfer_function": "dfwb.api.functions", "run_scene": "dfwb.api.studies",
    "sweep": "dfwb.api.studies", "grid": "dfwb.api.studies",
    "DescribingFunctionResponse": "dfwb.studies.responses", "LimitCycleResponse": "dfwb.studies.responses",
    "DfwbError": "dfwb.base.errors", "InputError": "dfwb.base.errors",
    "PlantError": "dfwb.base.errors", "RunError": "dfwb.base.errors",
    "Plant": "dfwb.plants", "names": "dfwb.plants", "plant": "dfwb.plants",
    "register": "dfwb.plants", "unregister": "dfwb.plants",
    "fmu_plant": "dfwb.foreign.plant", "FMUPlant": "dfwb.foreign.plant",
}

__all__ = [
    "__version__",
    "describing_function", "DescribingFunctionResponse",
    "limit_cycles", "LimitCycleResponse", "continuation", "ContinuationResponse", "hunting_map",
    "HuntingMapResponse", "limit_cycle_margin", "MarginResponse", "tune", "TuneResponse", "transfer_function",
    "run_scene", "sweep", "grid",
    "plant", "plants", "names", "Plant", "register", "unregister", "fmu_plant", "FMUPlant",
    "DfwbError", "PlantError", "InputError", "RunError",
]


def __getattr__(name):
    if name in _PUBLIC:
        value = getattr(importlib.import_module(_PUBLIC[name]), name)
        globals()[name] = value
        return value
    if name == "plants":
        return importlib.import_module("dfwb.plants")
    raise AttributeError(f"module 'dfwb' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))


if TYPE_CHECKING:  # the names as static analysers and IDEs see them
    from dfwb import plants
    from dfwb.api.functions import (
        continuation,
        describing_function,
        hunting_map,
        limit_cycle_margin,
        limit_cycles,
        transfer_function,
        tune,
    )
    from dfwb.api.studies import grid, run_scene, sweep
    from dfwb.base.errors import DfwbError, InputError, PlantError, RunError
    from dfwb.plants import Plant, names, plant, register, unregister
    from dfwb.studies.responses import (
        ContinuationResponse,
        DescribingFunctionResponse,
        HuntingMapResponse,
        LimitCycleResponse,
        MarginResponse,
        TuneResponse,
    )
