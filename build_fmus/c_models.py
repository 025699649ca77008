"""Small FMI 2.0 FMUs written from a few lines of C: foreign plants with known DFs.

:func:`build` writes one FMU from a few lines of C (the derivatives, the
output, the event indicators, the event update), compiled with the system C
compiler against fmpy's FMI headers. They are what another tool would hand a
user, and dfwb's analysis knows nothing of them but their model description:
the tests check the generic driver (:mod:`dfwb.foreign`) against their closed
forms, and ``dfwb bench`` measures its cost on them. The models:

- ``MassSpringDamper``: M x'' + c x' + k x = u, y = x; N = 1 / (k - M w^2 + j c w).
- ``Saturation``: y = clamp(u, -a, a), no state (a static nonlinearity with kinks);
  N(F) = (2/pi) (asin(a/F) + (a/F) sqrt(1 - (a/F)^2)) for F > a, else 1.
- ``DriftingMass``: a free mass launched at v0, M x'' = u: its position drifts by v0 T per period,
  and without that ramp N = -1 / (M w^2).
- ``Relay``: a relay with hysteresis, y = +-Y, switching up at u > a, down at u <= -a
  (memory); N(F) = 4 Y / (pi F) exp(-j asin(a/F)) for F > a.
"""

import math
import shutil
import subprocess
import zipfile
from pathlib import Path

from .core import CoreBuildError, compiler

TEMPLATE = r"""
#include <stdlib.h>
#include <string.h>
#include <math.h>
#include "fmi2Functions.h"

#define NX %(nx)d
#define NZ %(nz)d
#define NP %(np)d
typedef struct {
    double time, u, p[NP + 1], x[NX + 1], u0, du[3];
    int d;
    fmi2CallbackFunctions cb;
    fmi2ComponentEnvironment env;
    const char* name;
} Model;
#define P(i) (m->p[i])
#define X(i) (m->x[i])
#define U (m->u)
#define D (m->d)

static void derivatives(Model* m, double* dx) { (void)m; (void)dx; %(derivatives)s }
static double output(Model* m) { return %(output)s; }
static void indicators(Model* m, double* z) { (void)m; (void)z; %(indicators)s }
static void update(Model* m) { (void)m; %(update)s }
static void start(Model* m) { (void)m; %(start)s }

const char* fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char* fmi2GetVersion(void) { return fmi2Version; }
fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean l, size_t n, const fmi2String k[]) { return fmi2OK; }
fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String res,
                              const fmi2CallbackFunctions* cb, fmi2Boolean vis, fmi2Boolean log) {
    Model* m = calloc(1, sizeof(Model));
    double defaults[NP + 1] = {%(defaults)s};
    memcpy(m->p, defaults, sizeof(defaults));
    m->cb = *cb; m->env = cb->componentEnvironment; m->name = name;
    return m;
}
void fmi2FreeInstance(fmi2Component c) { free(c); }
fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean a, fmi2Real b, fmi2Real s, fmi2Boolean d, fmi2Real e) {
    ((Model*)c)->time = s; return fmi2OK; }
fmi2Status fmi2EnterInitializationMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) { start((Model*)c); return fmi2OK; }
fmi2Status fmi2Terminate(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2Reset(fmi2Component c) {
    Model* m = c; double defaults[NP + 1] = {%(defaults)s};
    memcpy(m->p, defaults, sizeof(defaults)); memset(m->x, 0, sizeof(m->x)); m->d = 0; m->u = 0; m->time = 0;
    return fmi2OK; }
fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    Model* m = c;
    for (size_t i = 0; i < n; i++) {
        if (vr[i] < NP) v[i] = m->p[vr[i]];
        else if (vr[i] == NP) v[i] = m->u;
        else if (vr[i] == NP + 1) v[i] = output(m);
        else return fmi2Error;
    }
    return fmi2OK; }
fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]) { return fmi2Error; }
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]) { return fmi2Error; }
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[]) { return fmi2Error; }
fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
    Model* m = c;
    for (size_t i = 0; i < n; i++) {
        if (vr[i] < NP) m->p[vr[i]] = v[i];
        else if (vr[i] == NP) m->u = v[i];
        else return fmi2Error;
    }
    return fmi2OK; }
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[]) { return fmi2Error; }
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[]) { return fmi2Error; }
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[]) { return fmi2Error; }
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate* s) {
    Model* m = c; Model* copy = *s ? *s : malloc(sizeof(Model)); *copy = *m; *s = copy; return fmi2OK; }
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) { *(Model*)c = *(Model*)s; return fmi2OK; }
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate* s) { free(*s); *s = NULL; return fmi2OK; }
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t* n) { return fmi2Error; }
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n) { return fmi2Error; }
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate* s) { return fmi2Error; }
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference a[], size_t na,
    const fmi2ValueReference b[], size_t nb, const fmi2Real dv[], fmi2Real r[]) { return fmi2Error; }
fmi2Status fmi2EnterEventMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo* e) {
    update((Model*)c);
    e->newDiscreteStatesNeeded = fmi2False; e->terminateSimulation = fmi2False;
    e->nominalsOfContinuousStatesChanged = fmi2False; e->valuesOfContinuousStatesChanged = fmi2False;
    e->nextEventTimeDefined = fmi2False; e->nextEventTime = 0; return fmi2OK; }
fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean n, fmi2Boolean* e, fmi2Boolean* t) {
    *e = fmi2False; *t = fmi2False; return fmi2OK; }
fmi2Status fmi2SetTime(fmi2Component c, fmi2Real t) { ((Model*)c)->time = t; return fmi2OK; }
fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t n) {
    memcpy(((Model*)c)->x, x, n * sizeof(double)); return fmi2OK; }
fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real dx[], size_t n) { derivatives(c, dx); return fmi2OK; }
fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real z[], size_t n) { indicators(c, z); return fmi2OK; }
fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t n) {
    memcpy(x, ((Model*)c)->x, n * sizeof(double)); return fmi2OK; }
fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x[], size_t n) {
    for (size_t i = 0; i < n; i++) x[i] = 1.0; return fmi2OK; }
/* co-simulation functions: not offered (the model description declares model exchange only) */
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference v[], size_t n,
    const fmi2Integer o[], const fmi2Real d[]) {
    Model* m = c;
    for (size_t i = 0; i < n; i++) {
        if (v[i] != NP || o[i] < 1 || o[i] > 3) return fmi2Error;
        m->du[o[i] - 1] = d[i];
    }
    return fmi2OK; }
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference v[], size_t n,
    const fmi2Integer o[], fmi2Real d[]) { return fmi2Error; }
static double input_at(Model* m, double s) {  /* the input s after the step's start: its Taylor polynomial */
    double value = m->u0, factor = 1.0;
    for (int k = 0; k < 3; k++) { factor *= s / (k + 1); value += m->du[k] * factor; }
    return value;
}
fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean n) {
    /* RK4 in substeps of at most 1 ms, the input interpolated from the derivatives given (held if none) */
    Model* m = c;
    int steps = (int)ceil(h / 1e-3 - 1e-9);
    if (steps < 1) steps = 1;
    double dt = h / steps, x0[NX + 1], k1[NX + 1], k2[NX + 1], k3[NX + 1], k4[NX + 1];
    m->u0 = m->u;
    for (int i = 0; i < steps; i++) {
        double s = i * dt;
        memcpy(x0, m->x, sizeof(x0));
        m->u = input_at(m, s); derivatives(m, k1);
        for (int j = 0; j < NX; j++) m->x[j] = x0[j] + dt / 2 * k1[j];
        m->u = input_at(m, s + dt / 2); derivatives(m, k2);
        for (int j = 0; j < NX; j++) m->x[j] = x0[j] + dt / 2 * k2[j];
        derivatives(m, k3);
        for (int j = 0; j < NX; j++) m->x[j] = x0[j] + dt * k3[j];
        m->u = input_at(m, s + dt); derivatives(m, k4);
        for (int j = 0; j < NX; j++) m->x[j] = x0[j] + dt / 6 * (k1[j] + 2 * k2[j] + 2 * k3[j] + k4[j]);
    }
    m->u = input_at(m, h);
    memset(m->du, 0, sizeof(m->du));
    m->time = t + h;
    return fmi2OK;
}
fmi2Status fmi2CancelStep(fmi2Component c) { return fmi2Error; }
fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status* v) { return fmi2Error; }
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real* v) { return fmi2Error; }
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer* v) { return fmi2Error; }
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean* v) { return fmi2Error; }
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String* v) { return fmi2Error; }
"""

MODELS = {
    "MassSpringDamper": dict(
        params=[("M", 1.0, "kg"), ("c", 0.2, "N.s/m"), ("k", 4.0, "N/m")], nx=2, nz=0,
        derivatives="dx[0] = X(1); dx[1] = (U - P(1) * X(1) - P(2) * X(0)) / P(0);",
        output="X(0)", indicators="", update="", start=""),
    "Saturation": dict(
        params=[("a", 1.0, "N")], nx=0, nz=2,
        derivatives="", output="U > P(0) ? P(0) : (U < -P(0) ? -P(0) : U)",
        indicators="z[0] = U - P(0); z[1] = U + P(0);", update="", start=""),
    "Relay": dict(
        params=[("Y", 1.0, "m"), ("a", 0.5, "N")], nx=0, nz=2,
        derivatives="", output="P(0) * D",
        indicators="z[0] = U - P(1); z[1] = U + P(1);",
        update="if (U - P(1) > 0) D = 1; else if (U + P(1) <= 0) D = -1;",
        start="D = U > 0 ? 1 : -1;"),
    "DriftingMass": dict(  # a free mass launched at v0: its position creeps by v0 T each period
        params=[("M", 1.0, "kg"), ("v0", 0.3, "m/s")], nx=2, nz=0,
        derivatives="dx[0] = X(1); dx[1] = U / P(0);", output="X(0)", indicators="", update="",
        start="X(1) = P(1);"),
}


def _description(name, model, interpolate):
    rows = []
    for vr, (param, start, unit) in enumerate(model["params"]):
        rows.append(f'<ScalarVariable name="{param}" valueReference="{vr}" causality="parameter" '
                    f'variability="fixed"><Real start="{start}" unit="{unit}"/></ScalarVariable>')
    n = len(model["params"])
    rows.append(f'<ScalarVariable name="u" valueReference="{n}" causality="input"><Real start="0" unit="N"/>'
                '</ScalarVariable>')
    rows.append(f'<ScalarVariable name="y" valueReference="{n + 1}" causality="output"><Real unit="m"/>'
                '</ScalarVariable>')
    states = "".join(f'<ScalarVariable name="x{i}" valueReference="{n + 2 + i}"><Real/></ScalarVariable>'
                     for i in range(model["nx"]))
    derivs = "".join(f'<ScalarVariable name="der(x{i})" valueReference="{n + 2 + model["nx"] + i}">'
                     f'<Real derivative="{n + 3 + i}"/></ScalarVariable>' for i in range(model["nx"]))
    units = {unit for _p, _s, unit in model["params"]} | {"N", "m"}
    unit_defs = "".join(f'<Unit name="{u}"/>' for u in sorted(units))
    structure = "".join(f'<Unknown index="{n + 3 + model["nx"] + i}"/>' for i in range(model["nx"]))
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="{name}" guid="{{dfwb-test-{name}}}"
  numberOfEventIndicators="{model['nz']}">
<ModelExchange modelIdentifier="{name}" canGetAndSetFMUstate="true"/>
<CoSimulation modelIdentifier="{name}" canGetAndSetFMUstate="true" canHandleVariableCommunicationStepSize="true"
  canInterpolateInputs="{'true' if interpolate else 'false'}"/>
<UnitDefinitions>{unit_defs}</UnitDefinitions>
<ModelVariables>{''.join(rows)}{states}{derivs}</ModelVariables>
<ModelStructure><Outputs><Unknown index="{n + 2}"/></Outputs>
<Derivatives>{structure}</Derivatives></ModelStructure>
</fmiModelDescription>
"""


def build(name, folder, interpolate=False, model=None):
    """Write ``folder/<name>.fmu`` and return its path: FMI 2.0, linux64, model exchange and co-simulation
    (RK4 in substeps of at most 1 ms), that co-simulation declaring ``canInterpolateInputs`` if
    ``interpolate`` (it takes input derivatives up to order 3 either way). ``model``: a dict as in
    :data:`MODELS` (default: ``MODELS[name]``). :class:`~dfwb.build_fmus.core.CoreBuildError` if it
    cannot be compiled."""
    import fmpy

    model = MODELS[name] if model is None else model
    folder = Path(folder)
    work = folder / f"{name}_{int(interpolate)}_build"
    binaries = work / "binaries" / "linux64"
    binaries.mkdir(parents=True, exist_ok=True)
    source = work / f"{name}.c"
    defaults = ", ".join(repr(float(start)) for _p, start, _u in model["params"]) or "0"
    source.write_text(TEMPLATE % dict(model, np=len(model["params"]), defaults=defaults))
    headers = Path(fmpy.__file__).parent / "c-code"
    command = compiler() + ["-shared", "-fPIC", "-O2", "-w", f"-I{headers}", "-o", str(binaries / f"{name}.so"),
                            str(source), "-lm"]
    run = subprocess.run(command, capture_output=True, text=True)
    if run.returncode != 0:
        shutil.rmtree(work)
        raise CoreBuildError(f"compiling the C model {name} failed (exit {run.returncode}): "
                             + (run.stderr.strip().splitlines() or ["no message"])[0])
    (work / "modelDescription.xml").write_text(_description(name, model, interpolate))
    fmu = folder / (f"{name}.fmu" if not interpolate else f"{name}Interpolating.fmu")
    with zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as archive:
        for path in sorted(work.rglob("*")):
            if path.is_file() and path.suffix != ".c":
                archive.write(path, path.relative_to(work).as_posix())
    shutil.rmtree(work)
    return fmu


def saturation_df(F, a=1.0):
    """N(F) of ``Saturation`` (real, frequency-independent)."""
    if F <= a:
        return 1.0
    r = a / F
    return 2.0 / math.pi * (math.asin(r) + r * math.sqrt(1.0 - r * r))


def relay_df(F, Y=1.0, a=0.5):
    """N(F) of ``Relay``, F > a (the hysteresis lags by asin(a/F))."""
    return 4.0 * Y / (math.pi * F) * complex(math.cos(math.asin(a / F)), -a / F)


def msd_df(omega, M=1.0, c=0.2, k=4.0):
    """N(omega) of ``MassSpringDamper`` (linear: independent of F)."""
    return 1.0 / complex(k - M * omega ** 2, c * omega)
