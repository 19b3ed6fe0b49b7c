"""The FMU's documentation/index.html, generated from the variable table and the physics' own docstrings.

Nothing here lists a variable by hand: the table is variables.VARIABLES with the start values the
completed modelDescription.xml declares, and the model's text is physics' docstrings, rendered from
their reStructuredText (numpydoc sections are section titles and definition lists to it) by docutils.
"""

from __future__ import annotations

import html
import inspect
import sys
import xml.etree.ElementTree as ET

from ..physics import Ball
from ..validation import exact
from .host_check import TESTED_PYTHON_HOSTS
from .variables import FMI3_VARIABLES, MODEL_NAME, SMALLEST_POSITIVE, VARIABLES


def index_html(model_description: bytes) -> str:
    """The FMU's documentation/index.html.

    Parameters
    ----------
    model_description : bytes
        The completed modelDescription.xml (its start values and default experiment are shown).

    Returns
    -------
    str
        A self-contained HTML page: the equations of both modes, every variable with its unit,
        range and start value, the events, what the host needs and how to check a result.

    Examples
    --------
    >>> page = index_html(open("modelDescription.xml", "rb").read())  # doctest: +SKIP
    >>> "<td>F_ext</td>" in page  # doctest: +SKIP
    True
    """
    root = ET.fromstring(model_description)
    fmi3 = root.get("fmiVersion", "").startswith("3")
    starts = _start_values(root)
    experiment = root.find("DefaultExperiment")
    e = html.escape
    api = "fmi3" if fmi3 else "fmi2"
    interfaces = "co-simulation (early return, event mode) and model exchange" if fmi3 else "co-simulation"
    if fmi3:  # pythonfmu3 passes no tolerance to the slave: rtol is the FMU's own parameter
        tolerance = ("The master's tolerance (fmi3EnterInitializationMode) is not passed on; the parameter rtol "
                     "sets CVODE's.")
    else:
        tolerance = ("A tolerance a master passes in fmi2SetupExperiment is used as rtol only where it is tighter "
                     "than rtol; a looser one is not used, and the FMU says so once in its log.")

    doc = rendered_docstring

    rows = "\n".join(
        f"<tr><td>{e(v.name)}</td><td>{e(v.causality)}{'' if v.type == 'Real' else ', ' + v.type}</td>"
        f"<td>{e(v.unit)}</td><td>{e(starts.get(v.name, ''))}</td><td>{e(_range(v.min, v.max))}</td>"
        f"<td>{e(v.description)}</td></tr>" for v in (*VARIABLES, *(FMI3_VARIABLES if fmi3 else ())))
    ball = Ball()
    python_version = f"{sys.version_info.major}.{sys.version_info.minor}"  # the build's, as the loader's
    return f"""<!DOCTYPE html>
<html lang="en">
<head><meta charset="utf-8"><title>{MODEL_NAME}: documentation</title>
<style>body {{font-family: sans-serif; max-width: 60em; margin: auto}} td, th {{border: 1px solid #ccc;
padding: 0.2em 0.5em}} table {{border-collapse: collapse}} code {{background: #eee}}</style></head>
<body>
<h1>{MODEL_NAME}</h1>
<p>{e(root.get("description", ""))}. FMI {e(root.get("fmiVersion", ""))} {interfaces},
{e(root.get("generationTool", ""))}.</p>
{doc(Ball)}

<h2>Equations</h2>
<table>
<tr><th>mode</th><th>equation</th><th>ends when</th></tr>
<tr><td>flight</td><td>h' = v, v' = -g + F_ext/m</td><td>h crosses R going down (impact)</td></tr>
<tr><td>contact</td><td>h' = v, m v' = -b v + k (R - h) - m g + F_ext</td>
<td>h crosses R going up (departure)</td></tr>
</table>
<p>The mode is a discrete state held between events.</p>
{doc(Ball.flow)}
<p>Contact force of the ground on the ball:</p>
{doc(Ball.contact_force)}
<p>The start mode:</p>
{doc(Ball.initial_mode)}
<p>A contact whose next maximum of h stays below R never ends: the ball comes to rest at</p>
{doc(Ball.rest_height)}
<p>({ball.rest_height():.15g} m with the defaults).</p>

<h2>Variables</h2>
<table>
<tr><th>name</th><th>causality</th><th>unit</th><th>start</th><th>range</th><th>description</th></tr>
{rows}
</table>
<p>A range "&gt; 0" is written min="{SMALLEST_POSITIVE!r}" in modelDescription.xml (FMI's min is inclusive).
Default experiment: {e(experiment.get("startTime", ""))} to {e(experiment.get("stopTime", ""))} s,
step {e(experiment.get("stepSize", ""))} s, tolerance {e(experiment.get("tolerance", ""))} (the default rtol).
{tolerance}</p>

<h2>Events</h2>
{doc(Ball.event_function)}
<p>Every {api}DoStep advances one persistent CVODE integrator and finds every impact and departure
inside the step by root-finding, so the result does not depend on the communication step. The host
sees events through the outputs <code>impacts</code> (counted since the start) and
<code>contact</code>; F_ext is held constant over each communication step.{_FMI3_EVENTS if fmi3 else ""}</p>

<h2>What the host needs</h2>
<p>A Python with numpy and scikit-sundae installed. A master that runs Python itself (FMPy,
libcosimpy) uses its own: an FMU built with CPython 3.11 was run in FMPy under CPython
{", ".join(TESTED_PYTHON_HOSTS)}. A master without Python (a C or C++ tool) starts a Python of the
version this FMU was built with, {e(python_version)}: the one it was built with, or else the first
matching <code>python3</code> on its PATH, which needs a shared libpython (tested with the build's own
Python). Hence needsExecutionTool="true". Binaries: Linux x86_64 only.
Invalid parameters give {api}Error with a message; FMU state can be got, set and serialized.</p>

<h2>How to check a result</h2>
<p>The reference result of the default experiment (the exact solution, the FMU's outputs on its
output grid) is shipped beside the FMU as <code>{MODEL_NAME}_ref.csv</code>. Any master's result,
as a CSV with a <code>time</code> and an <code>h</code> column, is judged against the exact
solution at its own times by</p>
<pre>pip install bouncingball
bouncingball check result.csv --start-value g=1.62 --start-value h=1.0 --tolerance 1e-6</pre>
<p>with the start values the master set; it exits 0 when the heights are within the tolerance and the
<code>impacts</code> column (if any) counts right, 1 when not. From Python:
<code>bouncingball.testing.check_result("result.csv", "article", {{"g": 1.62}})</code>.</p>
</body>
</html>
"""


_FMI3_EVENTS = """ A master that allows early return gets fmi3DoStep back at each impact and
departure, at its time, with eventHandlingNeeded when it uses event mode: it can change F_ext exactly
there. In model exchange the master integrates h and v; the event indicator <code>gap</code> = h - R
crosses 0 at each event, and fmi3UpdateDiscreteStates switches the mode."""


def _start_values(root) -> dict[str, str]:
    """Each variable's start value as the model description declares it (FMI 2.0 or 3.0)."""
    starts = {}
    for variable in root.find("ModelVariables"):
        if variable.tag == "ScalarVariable":  # FMI 2.0: the start on the typed child
            starts[variable.get("name")] = next(iter(variable)).get("start", "")
        else:  # FMI 3.0: on the variable itself, a String's as a <Start value=...> child
            start = variable.find("Start")
            starts[variable.get("name")] = variable.get("start", "" if start is None else start.get("value", ""))
    return starts


def rendered_docstring(obj) -> str:
    """obj's docstring as HTML, rendered by docutils; a docstring docutils warns about fails the build."""
    from docutils.core import publish_parts
    from docutils.utils import SystemMessage
    from docutils.writers.html5_polyglot import Writer

    try:
        parts = publish_parts(inspect.getdoc(obj), writer=Writer(), settings_overrides={
            "initial_header_level": 3, "doctitle_xform": False, "halt_level": 2, "report_level": 5,
            "warning_stream": False, "input_encoding": "unicode"})
    except SystemMessage as error:
        raise ValueError(f"the docstring of {obj.__qualname__} is not valid reStructuredText: {error}") from None
    return parts["body"]


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
