"""The runs whose results are pinned bit for bit across refactors of the core (tests/test_pinned_runs.py).

Every built-in scene under every contact law that takes it, on both CVODE engines and the exact solver, plus a
few runs through the stepping API; each reduced to its events and a sample of its grid, as float.hex strings.
`python tests/pinned_runs.py` rewrites tests/data/pinned_runs.json: run it only at a commit whose results are
the reference (a change of the numbers is a change of behaviour, to be argued in its own commit). The pins were
written at b7244be (PYTHONPATH=<its checkout>/src), each ball given its law's own parameters only.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

import bouncingball as bb
from bouncingball.scenes import BUILTIN_SCENES, load_scene

PINS = Path(__file__).parent / "data" / "pinned_runs.json"
LAWS = ("linear", "rigid", "linear-no-pull", "hunt-crossley")
ENGINES = ("sksundae", "compiled")
SAMPLES = 41  # grid points kept per run, evenly spread, the last one included
LONG = 100.0  # scenes longer than this [s] are cut to it: the pins are about the phase machine, not patience


def _hex(values) -> list[str]:
    return [float(x).hex() for x in np.asarray(values, dtype=float).ravel()]


def _ball(scene, law):
    # the law's own parameters only (a rigid ball reads neither k nor b, a Hunt-Crossley one not b: Ball refuses
    # them set, and the runs pinned with them set are the same bit for bit)
    own = {"linear": ("k", "b"), "rigid": (), "linear-no-pull": ("k", "b"), "hunt-crossley": ("k",)}[law]
    fields = {name: getattr(scene.ball, name) for name in ("m", "R", "g", *own)}
    if law == "rigid":
        fields.update(e=0.7, v_min=0.0)
    if law == "hunt-crossley":
        fields.update(n=1.5, alpha=0.05)
    return bb.Ball(contact=law, **fields)


def cases():
    """(key, thunk) for every pinned run; the thunk returns its reduced result (a dict of hex lists)."""
    for name in BUILTIN_SCENES:
        scene = load_scene(name)
        t_end = min(scene.t_end, LONG)
        for law in LAWS:
            ball = _ball(scene, law)
            if (law == "rigid" and scene.h0 < ball.R) or (law == "hunt-crossley" and name == "stiff-rest"):
                continue  # refused; and a Hunt-Crossley rest at k = 1e12 that CVODE crawls through for a minute
            for solver, engine in [("cvode", e) for e in ENGINES] + [("exact", None)]:
                if solver == "exact" and law == "hunt-crossley":
                    continue
                options = {"engine": engine} if engine else {}
                key = f"{name}/{law}/{solver}/{engine or '-'}"

                def run(ball=ball, scene=scene, t_end=t_end, solver=solver, options=options):
                    result = bb.simulate(ball, scene.h0, scene.v0, t_end, min(scene.output_interval, t_end),
                                         solver=solver, F_ext=scene.F_ext, **options)
                    keep = np.unique(np.linspace(0, len(result.t) - 1, SAMPLES).astype(int))
                    events = [(e.time, e.velocity) for e in result.events]
                    return {"h": _hex(result.h[keep]), "v": _hex(result.v[keep]), "events": _hex(events),
                            "kinds": [str(e.kind) for e in result.events],
                            "error_estimate": _hex([getattr(result, "error_estimate", float("nan")) or 0.0])}
                yield key, run
    for law in LAWS:
        for engine in ENGINES:
            yield f"article/{law}/advance-10ms/{engine}", lambda law=law, engine=engine: _stepped(law, engine)


def _stepped(law, engine):
    """The article's first 3 s in 10 ms steps of BallIntegrator.advance, as an FMU's doStep takes them."""
    from bouncingball.solvers.integrator import BallIntegrator
    from bouncingball.solvers.phase_machine.settings import CvodeSettings

    integrator = BallIntegrator(_ball(load_scene("article"), law), 2.0, 0.0, settings=CvodeSettings(engine=engine))
    h, v, estimate, events = [], [], [], []
    for i in range(1, 301):
        events += integrator.advance(i * 0.01)
        if i % 10 == 0:
            h.append(integrator.h)
            v.append(integrator.v)
            estimate.append(integrator.error_estimate)
    return {"h": _hex(h), "v": _hex(v), "error_estimate": _hex(estimate),
            "events": _hex([(e.time, e.velocity) for e in events]), "kinds": [str(e.kind) for e in events]}


def main() -> int:
    pins = {}
    for key, run in cases():
        try:
            pins[key] = run()
        except (ValueError, RuntimeError) as error:
            pins[key] = {"error": type(error).__name__}
        print(key, "error" if "error" in pins[key] else len(pins[key]["events"]) // 2, flush=True)
    PINS.write_text("{\n" + ",\n".join(f"{json.dumps(k)}: {json.dumps(v)}" for k, v in sorted(pins.items())) + "\n}\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
