"""The bouncingball command line's parser: its commands, options and help (cli.py runs them)."""

from __future__ import annotations

import argparse

from . import SOLVERS, __version__
from .contact_laws import CONTACT_LAWS

CONNECT_TIMEOUT = 10.0  # s: how long `sweep --scheduler` waits for the scheduler to answer
DESCRIPTION = "The bouncingball command line: run a scene, list scenes, build and validate the FMU, check a " \
    "master's result."


def build_parser() -> argparse.ArgumentParser:
    """The command line's parser: every command, option and help text."""
    from .fmu.validate import SCIPY_CAP, STAGES

    parser = argparse.ArgumentParser(prog="bouncingball", description=DESCRIPTION)
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    run = sub.add_parser("run", help="simulate a scene and print a summary")
    run.add_argument("scene", nargs="?", default="article",
                     help="built-in scene name or a .toml file (default: article)")
    run.add_argument("--solver", default="cvode", help=f"one of {', '.join(SOLVERS)} (default: cvode)")
    run.add_argument("--method", help="cvode: auto, Adams or BDF; scipy: RK45, DOP853, LSODA, Radau, BDF, ...")
    run.add_argument("--rtol", type=float, help="relative tolerance")
    run.add_argument("--atol", type=float, help="upper bound on the absolute error of h [m] (default: none, the "
                     "error is controlled relative to each phase's scale)")
    run.add_argument("--max-step", type=float, help="maximum step size [s] (0: unbounded)")
    run.add_argument("--engine", help="cvode: auto (default), compiled (needs numba: the fast extra) or sksundae")
    run.add_argument("--contact", metavar="LAW", help=f"the contact law: {' or '.join(CONTACT_LAWS)} (default: the "
                     "scene's; see the README's Contact laws)")
    run.add_argument("--e", type=float, help="the rigid law's coefficient of restitution, in [0, 1] (default: the "
                     "scene's, 0.7)")
    run.add_argument("--v-min", type=float, help="the rigid law's speed [m/s] below which a bounce ends on the ground "
                     "(default: the scene's, 0)")
    run.add_argument("--n", type=float, help="the Hunt-Crossley law's exponent of the penetration, in [1, 2.5] "
                     "(default: the scene's, 1.5; the other laws do not read it)")
    run.add_argument("--alpha", type=float, help="the Hunt-Crossley law's damping [s/m], >= 0 (default: the "
                     "scene's, 0; the other laws do not read it)")
    run.add_argument("--ground-amplitude", type=float, metavar="A", help="a vibrating ground, s(t) = A sin(2 pi F t + "
                     "P): its amplitude [m] (with --ground-frequency; solver cvode, any contact law, or exact: rigid, "
                     "linear or linear-no-pull)")
    run.add_argument("--ground-frequency", type=float, metavar="F", help="the vibrating ground's frequency [Hz]")
    run.add_argument("--ground-phase", type=float, metavar="P", help="the vibrating ground's phase [rad] "
                     "(default: 0)")
    run.add_argument("--ground-table", metavar="CSV", help="a ground through the points of this file: two columns, "
                     "time [s] and height [m], a header line allowed (a cubic spline through them; contact rigid)")
    run.add_argument("--t-end", type=float, help="end time [s] (default: the scene's)")
    run.add_argument("--output-interval", type=float, help="output interval [s] (default: the scene's)")
    run.add_argument("--output", metavar="CSV", help="write time,h,v to this file (-: to stdout, the summary then "
                                                     "goes to stderr)")
    run.add_argument("--events", metavar="CSV", help="write time,kind,v of each event to this file")
    run.add_argument("--plot", metavar="PNG", help="draw h(t), the events, the error and its estimate, for an "
                     "undamped ball the energy drift, and the last second zoomed")
    run.add_argument("--plot-range", metavar="T0:T1", help="draw only from T0 to T1 [s] (default: the whole run)")

    sub.add_parser("scenes", help="list the built-in scenes")

    build = sub.add_parser("build-fmu", help="build the FMU: FMI 2.0 co-simulation, or FMI 3.0 co-simulation and "
                                             "model exchange")
    build.add_argument("-o", "--output", help="where to write it (default: dist/BouncingBall.fmu, "
                                              "dist/BouncingBall3.fmu for --fmi-version 3)")
    build.add_argument("--fmi-version", type=fmi_version, default=2, metavar="{2,3}", help="FMI version: 2 (or 2.0) "
                       "or 3 (or 3.0) (default: 2)")
    check = sub.add_parser("validate", help="run the FMU through FMPy and compare it with CVODE, SciPy and the "
                                            "exact solution")
    check.add_argument("scene", nargs="?", default="article", help="built-in scene name or a .toml file "
                                                                   "(default: article)")
    check.add_argument("--fmu", help="the FMU to run (default: dist/BouncingBall.fmu, or dist/BouncingBall3.fmu for "
                                     "--fmi-version 3, built if missing or stale)")
    check.add_argument("--fmi-version", type=fmi_version, default=2, metavar="{2,3}", help="FMI version: 2 (or 2.0) "
                       "or 3 (or 3.0) (default: 2)")
    check.add_argument("--skip", action="append", default=[], metavar="STAGE",
                       help=f"a stage not to run: {', '.join(STAGES)} (repeatable; without exact, its row is left "
                            "out, the others are still judged by the exact solution)")
    check.add_argument("--time-cap", type=float, default=SCIPY_CAP, metavar="S",
                       help=f"wall time the SciPy stage may take before it is stopped [s] (default: {SCIPY_CAP:g})")
    judge = sub.add_parser("check", help="compare a master's result (CSV) with the exact solution at its own times")
    judge.add_argument("result", metavar="RESULT.csv", help="the CSV a master wrote (FMPy, OMSimulator, libcosim, "
                                                          "ecos, ...): a time and an h column (an impacts column is "
                                                          "checked too, parameter columns are taken)")
    judge.add_argument("scene", nargs="?", default="article", help="the scene the master ran: a built-in scene "
                                                                   "name or a .toml file (default: article)")
    from .fmu.variables import GROUND_FIELD_OF_START_VALUE, SCENE_FIELD_OF_START_VALUE

    judge.add_argument("--start-value", action="append", default=[], metavar="NAME=VALUE",
                       help=f"a start value the master set on the FMU ({', '.join(SCENE_FIELD_OF_START_VALUE)}, "
                            f"{', '.join(GROUND_FIELD_OF_START_VALUE)}, rtol, atol; repeatable)")
    judge.add_argument("--tolerance", type=float, default=1e-6, help="allowed max |h - h_exact| [m] (default: 1e-6)")
    judge.add_argument("--input-file", metavar="F.csv", help="the FMPy input file (time,F_ext) the master drove F_ext "
                       "with: F_ext is held over each communication step at the value FMPy applies at its start")
    judge.add_argument("--step-size", type=float, metavar="DT", help="with --input-file: the master's communication "
                       "step [s] (default: the result's times are the communication points)")
    judge.add_argument("--start-time", type=float, default=0.0, help="when the master started the run [s] "
                                                                     "(default: 0)")
    judge.add_argument("--instance", metavar="NAME", help="the instance of the ball to check when the file holds "
                                                          "several (ball for ball::h or model.root.ball.h)")
    bench = sub.add_parser("bench", help="benchmark error against run time (or, with --stability, the stability "
                                         "matrix) and write the results")
    bench.add_argument("--quick", action="store_true", help="a small run that CI can afford")
    study = bench.add_mutually_exclusive_group()
    study.add_argument("--hunt-crossley", action="store_true", help="the Hunt-Crossley law against DOP853 at a "
                                                                    "matched error, and write hunt_crossley.md")
    study.add_argument("--stability", action="store_true", help="run every scene with every solver under a time "
                                                                "cap and write stability.md")
    study.add_argument("--c-fmu", metavar="DIR", help="our FMU beside the Reference-FMUs' C BouncingBall in their "
                                                      "master fmusim (DIR holds fmusim, Ref_BouncingBall_fmi2.fmu "
                                                      "and Ref_BouncingBall_fmi3.fmu), and write c_fmu.md")
    study.add_argument("--first-use", action="store_true", help="time the compiled engine's first use from a wheel "
                                                                "installed in a fresh venv, and write first_use.md")
    bench.add_argument("--output-dir", default="bench-results",
                       help="where to write the results (default: bench-results; docs regenerates the committed ones)")
    sweep = sub.add_parser("sweep", help="a stability map over (k, damping, m, h0) for each solver, run on "
                                         "Dask (needs the [sweep] extra)")
    for name, default in (("k", "1e2:1e14:13 [N/m]; hunt-crossley: 1e3:1e9:13 [N/m^1.5]"),
                          ("zeta", "1e-4:1e2:7, the linear laws' damping ratio"), ("m", "1 [kg]"), ("h0", "2 [m]")):
        sweep.add_argument(f"--{name}", metavar="LO:HI:N", help=f"log-spaced values (default: {default})")
    sweep.add_argument("--alpha", metavar="VALUES", help="the Hunt-Crossley law's damping [s/m] (n = 1.5): values "
                       "and LO:HI:N log-spaced ranges, comma-separated (default: 0,1e-4:1:9)")
    sweep.add_argument("--contact", metavar="LAW", help="the balls' contact law: linear (default), linear-no-pull "
                       "(then CVODE alone by default: the article's and SciPy's algorithms model a force that is a "
                       "function of the state) or hunt-crossley (errors against a reference run per cell)")
    sweep.add_argument("--t-end", type=float, help="end time of each run [s] (default: 8)")
    sweep.add_argument("--solvers", help="comma-separated: cvode, cvode:Adams, cvode:BDF, article, scipy:METHOD "
                                         "(default: cvode,article,scipy:DOP853)")
    sweep.add_argument("--scheduler", metavar="ADDRESS", help="a running Dask scheduler, e.g. tcp://host:8786 "
                                                              "(default: a LocalCluster)")
    sweep.add_argument("--connect-timeout", type=float, default=CONNECT_TIMEOUT, metavar="S",
                       help=f"how long to wait for --scheduler to answer [s] (default: {CONNECT_TIMEOUT:g})")
    sweep.add_argument("--workers", type=int, help="LocalCluster worker processes (default: one per core)")
    sweep.add_argument("--time-cap", type=float, help="wall time a run may take [s] (default: 2; --quick: 1)")
    sweep.add_argument("--batch-size", type=int, help="runs per Dask task (default: from the measured overhead)")
    sweep.add_argument("--output-dir", default="sweep-results", help="where to write (default: sweep-results; "
                                                                     "docs regenerates the committed map)")
    sweep.add_argument("--resume", action="store_true", help="keep the runs already in --output-dir, run the rest")
    sweep.add_argument("--overwrite", action="store_true", help="delete the runs already in --output-dir and start "
                                                                "over (without it or --resume, a sweep refuses to "
                                                                "start where results are)")
    sweep.add_argument("--scaling", action="store_true", help="also time the grid on 1 worker and on as many as "
                                                              "the sweep used, for the doc's scaling line")
    sweep.add_argument("--quick", action="store_true", help="a 4 x 3 grid with a 1 s cap")
    parser.commands = sub.choices  # each command's parser, to refuse an unknown option in its own words
    return parser


def fmi_version(text: str) -> int:
    """--fmi-version's value: 2 for "2" or "2.0", 3 for "3" or "3.0" (as FMI writes its versions)."""
    versions = {"2": 2, "2.0": 2, "3": 3, "3.0": 3}
    if text.strip() not in versions:
        raise argparse.ArgumentTypeError(f"{text!r} is not allowed: it must be 2 (or 2.0) or 3 (or 3.0)")
    return versions[text.strip()]
