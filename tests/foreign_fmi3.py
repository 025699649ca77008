"""An FMI 3.0 co-simulation FMU in C that asks for its input inside its steps (intermediate update).

``MassSpringDamper3``: M x'' + c x' + k x = u, y = x, integrated by RK4 in
substeps of at most 1 ms. With ``intermediate``, it declares
``providesIntermediateUpdate`` and its input ``intermediateUpdate="true"``,
and calls the importer's intermediate-update callback at every RK4 stage,
asking for u there; without, u is held over each step. Every FMI 3.0 function
it does not need is a stub returning fmi3Error, written from fmpy's own
``fmi3FunctionTypes.h``.
"""

import re
import shutil
import subprocess
import zipfile
from pathlib import Path

import fmpy

HEADERS = Path(fmpy.__file__).parent / "c-code"

CODE = r"""
#include <stdlib.h>
#include <string.h>
#include <math.h>
#include "fmi3Functions.h"

typedef struct {
    double time, M, c, k, u, x, v;
    fmi3InstanceEnvironment env;
    fmi3IntermediateUpdateCallback update;
} Model;

const char* fmi3GetVersion(void) { return fmi3Version; }
fmi3Status fmi3SetDebugLogging(fmi3Instance i, fmi3Boolean l, size_t n, const fmi3String c[]) { return fmi3OK; }
fmi3Instance fmi3InstantiateCoSimulation(fmi3String name, fmi3String token, fmi3String resources, fmi3Boolean visible,
    fmi3Boolean logging, fmi3Boolean eventMode, fmi3Boolean earlyReturn, const fmi3ValueReference required[],
    size_t nRequired, fmi3InstanceEnvironment env, fmi3LogMessageCallback log, fmi3IntermediateUpdateCallback update) {
    Model* m = calloc(1, sizeof(Model));
    m->M = 1.0; m->c = 0.2; m->k = 4.0; m->env = env; m->update = INTERMEDIATE ? update : NULL;
    return m;
}
void fmi3FreeInstance(fmi3Instance i) { free(i); }
fmi3Status fmi3EnterInitializationMode(fmi3Instance i, fmi3Boolean td, fmi3Float64 tol, fmi3Float64 start,
    fmi3Boolean sd, fmi3Float64 stop) { ((Model*)i)->time = start; return fmi3OK; }
fmi3Status fmi3ExitInitializationMode(fmi3Instance i) { return fmi3OK; }
fmi3Status fmi3EnterStepMode(fmi3Instance i) { return fmi3OK; }
fmi3Status fmi3Terminate(fmi3Instance i) { return fmi3OK; }
fmi3Status fmi3Reset(fmi3Instance i) {
    Model* m = i; m->M = 1.0; m->c = 0.2; m->k = 4.0; m->u = m->x = m->v = m->time = 0.0; return fmi3OK; }
fmi3Status fmi3GetFloat64(fmi3Instance i, const fmi3ValueReference vr[], size_t n, fmi3Float64 v[], size_t nv) {
    Model* m = i;
    for (size_t j = 0; j < n; j++) {
        switch (vr[j]) {
            case 0: v[j] = m->time; break;
            case 1: v[j] = m->M; break;
            case 2: v[j] = m->c; break;
            case 3: v[j] = m->k; break;
            case 4: v[j] = m->u; break;
            case 5: v[j] = m->x; break;
            default: return fmi3Error;
        }
    }
    return fmi3OK;
}
fmi3Status fmi3SetFloat64(fmi3Instance i, const fmi3ValueReference vr[], size_t n, const fmi3Float64 v[], size_t nv) {
    Model* m = i;
    for (size_t j = 0; j < n; j++) {
        switch (vr[j]) {
            case 1: m->M = v[j]; break;
            case 2: m->c = v[j]; break;
            case 3: m->k = v[j]; break;
            case 4: m->u = v[j]; break;
            default: return fmi3Error;
        }
    }
    return fmi3OK;
}
static double input(Model* m, double t) {  /* asks the importer for u at t (intermediate update), else held */
    if (m->update) {
        fmi3Boolean early = fmi3False; fmi3Float64 earlyTime = 0.0;
        m->update(m->env, t, fmi3True, fmi3False, fmi3False, fmi3False, &early, &earlyTime);
    }
    return m->u;
}
static void rates(Model* m, double x, double v, double u, double* dx, double* dv) {
    *dx = v; *dv = (u - m->c * v - m->k * x) / m->M;
}
fmi3Status fmi3DoStep(fmi3Instance i, fmi3Float64 t, fmi3Float64 h, fmi3Boolean noSet, fmi3Boolean* event,
    fmi3Boolean* terminate, fmi3Boolean* early, fmi3Float64* last) {
    Model* m = i;
    int steps = (int)ceil(h / 1e-3 - 1e-9);
    if (steps < 1) steps = 1;
    double dt = h / steps;
    for (int s = 0; s < steps; s++) {
        double t0 = t + s * dt, x = m->x, v = m->v, k1x, k1v, k2x, k2v, k3x, k3v, k4x, k4v;
        double u0 = input(m, t0), um = input(m, t0 + dt / 2), u1 = input(m, t0 + dt);
        rates(m, x, v, u0, &k1x, &k1v);
        rates(m, x + dt / 2 * k1x, v + dt / 2 * k1v, um, &k2x, &k2v);
        rates(m, x + dt / 2 * k2x, v + dt / 2 * k2v, um, &k3x, &k3v);
        rates(m, x + dt * k3x, v + dt * k3v, u1, &k4x, &k4v);
        m->x = x + dt / 6 * (k1x + 2 * k2x + 2 * k3x + k4x);
        m->v = v + dt / 6 * (k1v + 2 * k2v + 2 * k3v + k4v);
    }
    m->time = t + h;
    *event = fmi3False; *terminate = fmi3False; *early = fmi3False; *last = m->time;
    return fmi3OK;
}
"""

DESCRIPTION = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="MassSpringDamper3" instantiationToken="{{dfwb-msd3}}">
<CoSimulation modelIdentifier="MassSpringDamper3" canHandleVariableCommunicationStepSize="true"
  providesIntermediateUpdate="{flag}"/>
<UnitDefinitions><Unit name="kg"/><Unit name="N"/><Unit name="m"/></UnitDefinitions>
<ModelVariables>
<Float64 name="time" valueReference="0" causality="independent" variability="continuous"/>
<Float64 name="M" valueReference="1" causality="parameter" variability="fixed" start="1" unit="kg"/>
<Float64 name="c" valueReference="2" causality="parameter" variability="fixed" start="0.2"/>
<Float64 name="k" valueReference="3" causality="parameter" variability="fixed" start="4"/>
<Float64 name="u" valueReference="4" causality="input" start="0" unit="N" intermediateUpdate="{flag}"/>
<Float64 name="y" valueReference="5" causality="output" unit="m"/>
</ModelVariables>
<ModelStructure><Output valueReference="5"/></ModelStructure>
</fmiModelDescription>
"""

IMPLEMENTED = {"GetVersion", "SetDebugLogging", "InstantiateCoSimulation", "FreeInstance", "EnterInitializationMode",
               "ExitInitializationMode", "EnterStepMode", "Terminate", "Reset", "GetFloat64", "SetFloat64", "DoStep"}


def _stubs():
    """Every other FMI 3.0 function, as a stub that refuses (from the header's function types)."""
    text = (HEADERS / "fmi3FunctionTypes.h").read_text()
    stubs = []
    for returns, name, params in re.findall(r"typedef\s+([\w\s\*]+?)\s*\b(fmi3\w+)TYPE\s*\(([^;]*?)\)\s*;", text,
                                            re.S):
        function = name[len("fmi3"):]
        if function in IMPLEMENTED or "Callback" in name:
            continue
        body = {"fmi3Status": "return fmi3Error;", "fmi3Instance": "return NULL;"}.get(returns.strip(), "")
        stubs.append(f"{returns} {name}({params}) {{ {body} }}")
    return "\n".join(stubs)


def build(folder, intermediate=True):
    """``folder/MassSpringDamper3.fmu`` (with or without intermediate update) and its path."""
    folder = Path(folder)
    work = folder / f"msd3_{int(intermediate)}"
    binaries = work / "binaries" / "x86_64-linux"
    binaries.mkdir(parents=True, exist_ok=True)
    source = work / "model.c"
    source.write_text(CODE.replace("INTERMEDIATE", "1" if intermediate else "0") + _stubs())
    subprocess.run(["gcc", "-shared", "-fPIC", "-O2", "-w", f"-I{HEADERS}", "-o",
                    str(binaries / "MassSpringDamper3.so"), str(source), "-lm"], check=True)
    (work / "modelDescription.xml").write_text(DESCRIPTION.format(flag="true" if intermediate else "false"))
    fmu = folder / ("MassSpringDamper3.fmu" if intermediate else "MassSpringDamper3Held.fmu")
    with zipfile.ZipFile(fmu, "w") as archive:
        for path in sorted(work.rglob("*")):
            if path.is_file() and path.suffix != ".c":
                archive.write(path, path.relative_to(work).as_posix())
    shutil.rmtree(work)
    return fmu
