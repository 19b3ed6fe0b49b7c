"""The FMU's documentation/index.html, for the user of a master: generated from the variable table.

As in the model description, every variable's row comes from variables.VARIABLES (FMI 3.0: with
FMI3_VARIABLES), its type and start value as the completed modelDescription.xml declares them.
The accuracy on the page is measured here, at build time: the default experiment run through the
slave's own do_step (slave_base.BallSlave, as the FMU runs it, without an FMI library), compared
with the exact solution. Where matplotlib is installed the page shows that run; build-fmu does not
need matplotlib, and without it the page says so. No timings: they would make two builds differ.
"""

from __future__ import annotations

import base64
import enum
import html
import io
import sys
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from importlib.metadata import version as installed_version

import numpy as np

from ..accuracy import Accuracy, ExactOnGrid, accuracy_of, exact_on_grid
from ..physics import Ball
from ..scenes import load_scene
from ..solvers.result import SimulationResult, SolverStats, output_grid
from ..validation import exact
from .host_check import TESTED_PYTHON_HOSTS
from .slave_base import DEFAULT_ENGINE, BallSlave
from .variables import EVENT_INDICATOR, FMI3_VARIABLES, MODEL_NAME, SMALLEST_POSITIVE, SOLUTION_OUTPUTS, VARIABLES

PLOT_DPI = 80
# do_step calls to reach one communication point: one, and with early return one more per event inside the step
MAX_CALLS_PER_STEP = 16
BAD_VALUE = ("m", -1.0)  # the refusal the page quotes, produced by the slave itself at build time


class _Status(enum.IntEnum):
    ok = 0
    warning = 1
    error = 3


class _Host(BallSlave):
    """The FMU's slave driven directly: its variables read and set by name, its log kept in a list."""

    STATUS = _Status

    def __init__(self, stop_at_event: bool):
        self.getters, self.setters, self.messages = {}, {}, []
        self.STOP_AT_EVENT = stop_at_event
        super().__init__()

    def _register(self, variable, getter, setter) -> None:
        self.getters[variable.name], self.setters[variable.name] = getter, setter

    def log(self, message, status=_Status.ok, *args, **kwargs) -> None:
        self.messages.append((status, message))

    def errors(self) -> list[str]:
        return [message for status, message in self.messages if status >= _Status.error]


@dataclass(frozen=True)
class DefaultRun:
    """The default experiment as the FMU's co-simulation computes it, and the exact solution there."""

    t: np.ndarray
    h: np.ndarray
    v: np.ndarray
    impacts: np.ndarray
    exact: ExactOnGrid
    accuracy: Accuracy
    max_velocity_error: float
    calls: int  # do_step calls (more than the communication points with early return)
    engine: str  # the engine that ran (DEFAULT_ENGINE "auto": the compiled one where numba is installed)


def default_run(stop_at_event: bool = False) -> DefaultRun:
    """Run the default experiment through the slave's do_step, one call per communication point (FMI 3.0:
    stepped on from each event it returns early at), and compare it with the exact solution."""
    scene = load_scene("article")
    t = output_grid(0.0, scene.t_end, scene.output_interval)
    slave = _Host(stop_at_event)
    slave.setup_experiment(0.0, scene.t_end)
    slave.exit_initialization_mode()
    h, v, impacts = np.empty_like(t), np.empty_like(t), np.zeros(len(t), dtype=int)
    calls = 0
    for i, target in enumerate(t):
        calls_to_target = 0
        while (now := slave._integrator.t) < target:
            if calls_to_target == MAX_CALLS_PER_STEP:
                raise RuntimeError(f"the FMU's default experiment did not reach t = {target!r} s in "
                                   f"{MAX_CALLS_PER_STEP} calls of do_step")
            calls_to_target += 1
            if not slave.do_step(now, target - now):
                raise RuntimeError(f"the FMU's default experiment failed at t = {now!r} s: {slave.errors()}")
        calls += calls_to_target
        h[i], v[i], impacts[i] = slave.getters["h"](), slave.getters["v"](), slave.getters["impacts"]()
    if slave.errors():
        raise RuntimeError(f"the FMU's default experiment logged errors: {slave.errors()}")
    on_grid = exact_on_grid(t, scene.ball, scene.h0, scene.v0, scene.F_ext)
    accuracy = accuracy_of(on_grid, h, impacts=int(impacts[-1]))
    return DefaultRun(t, h, v, impacts, on_grid, accuracy, float(np.max(np.abs(v - on_grid.v))), calls,
                      slave._integrator.engine)


def refusal(stop_at_event: bool = False) -> str:
    """What the FMU logs with its error status for BAD_VALUE set before initialisation."""
    slave = _Host(stop_at_event)
    name, value = BAD_VALUE
    slave.setters[name](value)
    slave.setup_experiment(0.0)
    slave.exit_initialization_mode()
    return slave.errors()[0]


def index_html(model_description: bytes) -> str:
    """The FMU's documentation/index.html, from its completed modelDescription.xml (types, start values).

    A self-contained HTML page: the model, its variables, what each interface does, the accuracy
    measured at build time, what the host Python needs, a plot of the default run where
    matplotlib is installed, and how to check a result against the reference.
    """
    root = ET.fromstring(model_description)
    fmi3 = root.get("fmiVersion", "").startswith("3")
    api = "fmi3" if fmi3 else "fmi2"
    run = default_run(stop_at_event=fmi3)
    e = html.escape
    return f"""<!DOCTYPE html>
<html lang="en">
<head><meta charset="utf-8"><title>{MODEL_NAME}</title>
<style>body {{font-family: sans-serif; max-width: 62em; margin: auto; line-height: 1.4}}
td, th {{border: 1px solid #ccc; padding: 0.2em 0.5em; vertical-align: top}} table {{border-collapse: collapse}}
code {{background: #eee}} img {{max-width: 100%}}</style></head>
<body>
<h1>{MODEL_NAME}</h1>
<p>{e(root.get("description", ""))}. FMI {e(root.get("fmiVersion", ""))}
{"co-simulation and model exchange" if fmi3 else "co-simulation"}; {e(root.get("generationTool", ""))}.</p>
{_model_section()}
{_variables_section(root, fmi3)}
{_interfaces_section(api, fmi3)}
{_accuracy_section(run, api, fmi3)}
{_host_section()}
{_plot_section(run, api)}
{_reference_section()}
</body>
</html>
"""


def _model_section() -> str:
    ball = Ball()
    return f"""<h2>The model</h2>
<p>A ball of mass m and radius R falls under gravity g onto rigid ground. Its state is the height h of
its centre and its velocity v (upwards positive). While h &gt; R it flies; while h &lt; R it is in
contact, and the ground pushes it back through a spring of stiffness k and a damper b:</p>
<table>
<tr><th>mode</th><th>equations</th><th>ends with</th></tr>
<tr><td>flight</td><td>h' = v, v' = -g + F_ext/m</td>
<td>an <b>impact</b>: h crosses R going down</td></tr>
<tr><td>contact</td><td>h' = v, m v' = -b v + k (R - h) - m g + F_ext</td>
<td>a <b>departure</b>: h crosses R going up</td></tr>
</table>
<p>The mode is a discrete state, switched only at these two events; contact_force is
k (R - h) - b v in contact and 0 in flight. A contact that can no longer lift the ball above R ends
at rest, at h = R - (m g - F_ext)/k ({ball.rest_height():.15g} m with the start values below).
The output <code>impacts</code> counts the impacts since the start, <code>contact</code> is true in
contact.</p>
<p>That is <code>contact_law</code> = linear, the default. With <code>contact_law</code> = rigid the ball
does not deform (k and b play no part): at each impact on h = R its velocity reverses, v+ = -e v-. A
bounce that would leave slower than <code>v_min</code> ends at rest on R; with <code>v_min</code> = 0
the infinitely many bounces before the Zeno time are summed exactly in co-simulation. A resting ball
leaves R when F_ext exceeds m g. In model exchange an impact is a jump of the state
(valuesOfContinuousStatesChanged), and a bounce lower than the master can follow (100 rtol R) ends at
rest.</p>
<p>With <code>contact_law</code> = linear-no-pull the spring and damper's force max(0, k (R - h) - b v)
never pulls: below R the ball is pressed while that force is positive and free (the flight's parabola)
where it would pull, switching where the force crosses 0 (a release, an engagement) and departing where a
free ball reaches R. <code>contact</code> is true while the ground pushes.</p>
<p>With <code>contact_law</code> = hunt-crossley the ground's force is Hunt and Crossley's
k delta^n (1 + 3/2 alpha delta') for the penetration delta = R - h (<code>n</code>: 1.5 for Hertz's sphere;
<code>k</code> then in N/m^n; b plays no part), clipped at 0 where it would pull: no jump of the force at
an impact or a departure, and a restitution that falls with impact speed (1 - alpha v to first order). In
co-simulation the FMU's CVODE integrates each contact; in model exchange the master does, the event
indicator h - R as under the linear law (the clip is in the derivative).</p>
<p>The ground may vibrate, under every law: <code>ground_amplitude</code> A, <code>ground_frequency</code> f and
<code>ground_phase</code> p make it a table at s(t) = A sin(2 pi f t + p) (A = 0, the default: the still
ground). Contact is then where h = R + s(t), the laws act on the deflection R + s - h and its rate s' - v, and a
rigid impact on the velocity relative to the table, v+ - s' = -e (v- - s'); a rigid ball that stops bouncing
rides the table until its acceleration falls below -(g - F_ext/m). h, v and a stay in the world's frame. In
co-simulation the FMU's CVODE runs on the table (no event missed: each step is searched for a graze); in model
exchange the derivatives, the event indicator (h - R - s(t) in flight) and the mode switches are taken in the
table's frame, and <code>error_estimate</code> measures the master's error there against the table's exact
flows.</p>"""


def _variables_section(root: ET.Element, fmi3: bool) -> str:
    declared = _declared(root)
    rows = []
    for variable in (*VARIABLES, *(FMI3_VARIABLES if fmi3 else ())):
        kind, start = declared[variable.name]
        cells = (variable.name, variable.causality, variable.variability, kind, variable.unit, start,
                 _range(variable.min, variable.max), variable.description)
        rows.append("<tr>" + "".join(f"<td>{html.escape(cell)}</td>" for cell in cells) + "</tr>")
    experiment = root.find("DefaultExperiment")
    rows = "\n".join(rows)
    return f"""<h2>Variables</h2>
<p>Parameters and the start values of h and v are set before initialisation; only the input F_ext can
change afterwards (between steps).</p>
<table>
<tr><th>name</th><th>causality</th><th>variability</th><th>type</th><th>unit</th><th>start</th><th>range</th>
<th>description</th></tr>
{rows}
</table>
<p>A range "&gt; 0" is written min="{SMALLEST_POSITIVE!r}" in modelDescription.xml (FMI's min is
inclusive). Default experiment: from {html.escape(experiment.get("startTime", ""))} to
{html.escape(experiment.get("stopTime", ""))} s, communication step {html.escape(experiment.get("stepSize", ""))} s,
tolerance {html.escape(experiment.get("tolerance", ""))} (the default rtol).</p>"""


def _interfaces_section(api: str, fmi3: bool) -> str:
    example = html.escape(refusal(stop_at_event=fmi3))
    name, value = BAD_VALUE
    common = f"""<p>Each {api}DoStep advances one CVODE integrator that persists from step to step
(SUNDIALS, through scikit-sundae) and finds every impact and departure inside the step by
root-finding, so the result at a communication point does not depend on the communication step.
F_ext is held constant over each step. The FMU state can be got, set and serialized; a restored state
continues bit for bit.</p>
<p>A value outside its range is answered with <b>{api}Error</b> and one line in the master's log
naming the value; the instance stays usable. With {name} = {value:g}, {api}ExitInitializationMode
returns {api}Error and logs:</p>
<pre>{example}</pre>"""
    if not fmi3:
        return f"""<h2>Interface: FMI 2.0 co-simulation</h2>
{common}
<p>A tolerance the master passes in fmi2SetupExperiment replaces rtol only where it is tighter; a looser
one is not used, and the FMU says so once in its log.</p>"""
    return f"""<h2>Interfaces: FMI 3.0 co-simulation and model exchange</h2>
<h3>Co-simulation, with early return and event mode</h3>
{common}
<p>A master that allows early return (fmi3InstantiateCoSimulation's earlyReturnAllowed) gets
fmi3DoStep back at each impact and departure inside the step, with earlyReturn = true and
lastSuccessfulTime the event's time. If it also uses event mode (eventModeUsed), eventHandlingNeeded
is true: it enters event mode there and can change F_ext exactly at the event. A master that does not
allow early return gets every step to its end. The master's tolerance is not passed on by
pythonfmu3: the parameter rtol sets CVODE's.</p>
<h3>Model exchange, with its event indicator</h3>
<p>The master integrates the continuous states x = h - R and v from their derivatives der(x) = v and der(v)
of the current mode; the FMU's CVODE is not used. The one event indicator <code>{EVENT_INDICATOR}</code>
= h - R crosses 0 downwards at an impact and upwards at a departure; at that state event the master
enters event mode and fmi3UpdateDiscreteStates switches the mode (and counts the impact). The
accuracy is that of the master's integrator and its event location.</p>"""


def _accuracy_section(run: DefaultRun, api: str, fmi3: bool) -> str:
    accuracy = run.accuracy
    worst = int(np.argmax(np.abs(run.h - run.exact.h)))
    wrong_counts = int(np.count_nonzero(run.impacts != run.exact.impacts))
    how = (f"{run.calls} fmi3DoStep calls with early return at each event" if fmi3 else
           f"{run.calls} fmi2DoStep calls")
    return f"""<h2>Accuracy</h2>
<p>Measured when this FMU was built: its default experiment (start values above) run through the
FMU's own co-simulation step with the default settings (rtol = {_default_rtol()}, engine
{DEFAULT_ENGINE}, which ran the {run.engine} engine at build), {how} to {len(run.t)} communication points,
compared with the exact piecewise-analytic solution at the same times:</p>
<table>
<tr><td>max |h - h_exact|</td><td>{accuracy.max_height_error:.2e} m (at t = {run.t[worst]:.6g} s)</td></tr>
<tr><td>max |v - v_exact|</td><td>{run.max_velocity_error:.2e} m/s</td></tr>
<tr><td>impacts</td><td>{accuracy.events_found} counted, {accuracy.events_exact} in the exact solution;
the count differs from the exact one at {wrong_counts} of the {len(run.t)} points</td></tr>
</table>
<p>A tighter rtol lowers the error; an atol bounds the absolute error of h. The value at a given time
does not depend on the communication steps taken to reach it: a master stepping otherwise gets the
same values at the same times.{" In model exchange the accuracy is the master's." if fmi3 else ""}</p>"""


def _default_rtol() -> str:
    from ..solvers.cvode import CvodeSettings

    return exact(CvodeSettings().rtol)


def _host_section() -> str:
    python_version = f"{sys.version_info.major}.{sys.version_info.minor}"  # the build's, as the loader's
    built_with = ", ".join(f"{name} {installed_version(name)}" for name in ("numpy", "scikit-sundae"))
    return f"""<h2>What the host needs</h2>
<p>The FMU runs its model in Python (needsExecutionTool="true"): the host needs a Python with
<b>numpy and scikit-sundae</b> (this FMU was built with {html.escape(built_with)}), and <b>numba</b> for
the parameter engine = "compiled" (or "auto" to use it where installed). A master that runs Python
itself (FMPy, libcosimpy) uses its own: an FMU built with CPython 3.11 was run in FMPy under CPython
{", ".join(TESTED_PYTHON_HOSTS)}. A master without Python (a C or C++ tool) starts a Python of the
version this FMU was built with, {python_version}: the one it was built with, or else the first
matching <code>python3</code> on its PATH, which needs a shared libpython. Binaries: Linux x86_64
only. Where a package is missing, instantiation fails with a message naming it.</p>"""


def _plot_section(run: DefaultRun, api: str) -> str:
    png = _plot_png(run, api)
    if png is None:
        return """<h2>The default run</h2>
<p>No plot: matplotlib was not installed where this FMU was built.</p>"""
    return f"""<h2>The default run</h2>
<p>The FMU's h over the default experiment, the exact solution, and the FMU's error against it.</p>
<img alt="h(t) of the default run, and its error" src="data:image/png;base64,{base64.b64encode(png).decode()}">"""


def _plot_png(run: DefaultRun, api: str) -> bytes | None:
    try:
        import matplotlib
    except ImportError:
        return None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..plotting import height_figure

    ball = run.exact.solution.ball
    result = SimulationResult(f"FMU ({api}DoStep)", ball, run.t, run.h, run.v, [], None, SolverStats())
    title = (f"{MODEL_NAME}, default experiment: {run.accuracy.events_found} impacts counted "
             f"({run.accuracy.events_exact} exact)")
    fig = height_figure(result, run.exact.result(), title)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=PLOT_DPI, metadata={"Software": None})  # the same bytes each build
    plt.close(fig)
    return buffer.getvalue()


def _reference_section() -> str:
    return f"""<h2>Reference result, and how to check a result</h2>
<p><code>bouncingball build-fmu</code> writes the reference result of the default experiment beside
the FMU, named after it (<code>{MODEL_NAME}_ref.csv</code> beside <code>{MODEL_NAME}.fmu</code>): the exact
solution at every communication point, in the columns time, {", ".join(SOLUTION_OUTPUTS)}.
Any master's result, as a CSV with a <code>time</code> and an <code>h</code> column, is judged
against the exact solution at its own times by</p>
<pre>pip install -e .   # in a checkout of bouncingball (it is not on PyPI)
bouncingball check result.csv --start-value g=1.62 --start-value h=1.0 --tolerance 1e-6</pre>
<p>with the start values the master set; it exits 0 when the heights are within the tolerance and the
<code>impacts</code> column (if any) counts right, 1 when not.</p>"""


def _declared(root: ET.Element) -> dict[str, tuple[str, str]]:
    """Each variable's type and start value as the model description declares them (FMI 2.0 or 3.0)."""
    declared = {}
    for variable in root.find("ModelVariables"):
        if variable.tag == "ScalarVariable":  # FMI 2.0: the type and start on the typed child
            typed = next(iter(variable))
            declared[variable.get("name")] = (typed.tag, typed.get("start", ""))
        else:  # FMI 3.0: the variable's tag is its type; a String's start is a <Start value=...> child
            start = variable.find("Start")
            declared[variable.get("name")] = (variable.tag, variable.get(
                "start", "" if start is None else start.get("value", "")))
    return declared


def _range(low: float | None, high: float | None) -> str:
    if low == SMALLEST_POSITIVE:
        text = "> 0"
    elif low is not None:
        text = f">= {exact(low)}"
    else:
        text = ""
    if high is not None:
        text = f"{text}, <= {exact(high)}" if text else f"<= {exact(high)}"
    return text
