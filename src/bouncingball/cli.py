"""The bouncingball command line: run a scene, list scenes, build and validate the FMU, check a master's result."""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import difflib
import os
import sys
import warnings
from collections.abc import Sequence

from . import SOLVERS, AccuracyWarning, __version__
from .contact_laws import CONTACT_LAWS
from .output import STANDARD_OUTPUT

EXIT_BAD_INPUT = 2
EXIT_SOLVER_FAILED = 1
EXIT_CHECK_FAILED = 1  # `check`: the result is not within the tolerance of the exact solution
EXIT_INTERRUPTED = 130  # 128 + SIGINT, as shells report it
CONNECT_TIMEOUT = 10.0  # s: how long `sweep --scheduler` waits for the scheduler to answer
PROGRESS_AFTER = 2.0  # s: `run` shows a progress bar once it has taken this long (on a terminal, with tqdm)
EXIT_BROKEN_PIPE = 141  # 128 + SIGPIPE: the reader (`| head`) stopped reading
# The optional modules a command may need, and the extra that installs each.
EXTRA_OF_MODULE = {"fmpy": "fmu", "pythonfmu": "fmu", "docutils": "fmu", "scipy": "reference", "matplotlib": "plot",
                   "tqdm": "bench", "dask": "sweep", "distributed": "sweep", "pandas": "sweep", "pyarrow": "sweep"}


def _build_parser() -> argparse.ArgumentParser:
    from .fmu.validate import SCIPY_CAP, STAGES

    parser = argparse.ArgumentParser(prog="bouncingball", description=__doc__)
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
    run.add_argument("--engine", help="cvode: auto (default), compiled (needs numba: pip install "
                                      "'bouncingball[fast]') or sksundae")
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
    build.add_argument("--fmi-version", type=int, choices=(2, 3), default=2, help="FMI version (default: 2)")
    check = sub.add_parser("validate", help="run the FMU through FMPy and compare it with CVODE, SciPy and the "
                                            "exact solution")
    check.add_argument("scene", nargs="?", default="article", help="built-in scene name or a .toml file "
                                                                   "(default: article)")
    check.add_argument("--fmu", help="the FMU to run (default: dist/BouncingBall.fmu, or dist/BouncingBall3.fmu for "
                                     "--fmi-version 3, built if missing or stale)")
    check.add_argument("--fmi-version", type=int, choices=(2, 3), default=2, help="FMI version (default: 2)")
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
    from .fmu.variables import SCENE_FIELD_OF_START_VALUE

    judge.add_argument("--start-value", action="append", default=[], metavar="NAME=VALUE",
                       help=f"a start value the master set on the FMU ({', '.join(SCENE_FIELD_OF_START_VALUE)}, "
                            "rtol, atol; repeatable)")
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
    sweep.add_argument("--scaling", action="store_true", help="also time the grid on 1 worker and on as many as "
                                                              "the sweep used, for the doc's scaling line")
    sweep.add_argument("--quick", action="store_true", help="a 4 x 3 grid with a 1 s cap")
    parser.commands = sub.choices  # each command's parser, to refuse an unknown option in its own words
    return parser


def _run(args: argparse.Namespace) -> int:
    if args.output == STANDARD_OUTPUT:  # the CSV alone on stdout, for a pipe; what `run` says goes to stderr
        stdout = sys.stdout
        with contextlib.redirect_stdout(sys.stderr):
            return _run_and_summarise(args, csv_stream=stdout)
    return _run_and_summarise(args)


def _check_outputs(args: argparse.Namespace) -> None:
    """Every output path and format, before the work, so that none of it is lost."""
    from .output import check_output_path

    for option in ("output", "events", "plot"):
        path = getattr(args, option)
        if path == STANDARD_OUTPUT and option != "output":
            raise ValueError(f"--{option} = {path!r} is not allowed: only --output writes to stdout")
        if path and path != STANDARD_OUTPUT:
            check_output_path(f"--{option}", path)
    if args.plot:
        from .plotting import require_matplotlib

        require_matplotlib()
        from matplotlib.backend_bases import FigureCanvasBase

        formats = FigureCanvasBase.get_supported_filetypes()
        suffix = os.path.splitext(args.plot)[1].lstrip(".").lower() or "png"
        if suffix not in formats:
            raise ValueError(f"--plot = {args.plot!r} is not allowed: its format {suffix!r} is not one of "
                             f"{', '.join(sorted(formats))}")


def _run_and_summarise(args: argparse.Namespace, csv_stream=None) -> int:
    from .accuracy import accuracy_of_result
    from .output import print_solution_csv, write_events_csv, write_solution_csv
    from .run_report import first_use_note, plural, restitution_line
    from .scenes import load_scene

    scene = load_scene(args.scene)
    law = {name: getattr(args, name) for name in ("contact", "e", "v_min", "n", "alpha")
           if getattr(args, name) is not None}
    if law:
        scene = dataclasses.replace(scene, ball=dataclasses.replace(scene.ball, **law))
    _check_outputs(args)
    plot_range = None
    if args.plot_range is not None:
        from .plotting import parse_time_range

        t_end = scene.t_end if args.t_end is None else args.t_end
        plot_range = parse_time_range("--plot-range", args.plot_range, 0.0, t_end)
    options = {name: getattr(args, name) for name in ("method", "rtol", "atol", "max_step", "engine")
               if getattr(args, name) is not None}
    if args.t_end is not None:
        options["t_end"] = args.t_end
    if args.output_interval is not None:
        options["output_interval"] = args.output_interval
    if args.solver == "scipy":
        print(f"bouncingball: running the article's SciPy algorithm on {scene.name} (minutes on a stiff scene; "
              "Ctrl-C stops it)", file=sys.stderr)
    with _progress_bar(options.get("t_end", scene.t_end)) as progress, warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", AccuracyWarning)
        if progress is not None and args.solver in ("cvode", "scipy"):
            options["progress"] = progress
        result = scene.simulate(args.solver, **options)
    for warning in caught:  # AccuracyWarning as one line; any other as Python shows it
        if issubclass(warning.category, AccuracyWarning):
            print(f"bouncingball: warning: {warning.message}", file=sys.stderr)
        else:
            warnings.showwarning(warning.message, warning.category, warning.filename, warning.lineno)
    # The Hunt-Crossley law has no exact solution to measure the run against: its own error estimate says how right.
    judged = result.solver != "exact" and not scene.ball.hunt_crossley
    accuracy, exact_on_grid = accuracy_of_result(result, scene.h0, scene.v0) if judged else (None, None)
    exact = result if result.solver == "exact" else None if exact_on_grid is None else exact_on_grid.result()

    ball = scene.ball
    print(f"scene {scene.name}: {scene.description}")
    if ball.rigid:
        law = f"rigid contact, e = {ball.e:g}, v_min = {ball.v_min:g} m/s"
    elif ball.hunt_crossley:
        law = f"Hunt-Crossley contact, k = {ball.k:g} N/m^{ball.n:g}, n = {ball.n:g}, alpha = {ball.alpha:g} s/m"
    else:
        law = ("no-pull contact, " if ball.no_pull else "") + f"k = {ball.k:g} N/m, b = {ball.b:g} N s/m"
    print(f"  ball        m = {ball.m:g} kg, {law}, R = {ball.R:g} m, g = {ball.g:g} m/s2")
    print(f"  start       h0 = {scene.h0:.15g} m, v0 = {scene.v0:g} m/s; {result.t[0]:g} to {result.t[-1]:g} s, "
          f"output every {result.t[1] - result.t[0]:g} s")
    settings = ", ".join(f"{key} {value}" for key, value in result.options.items())
    print(f"  solver      {result.solver}" + (f" ({settings})" if settings else ""))
    _print_events(result, exact, exact_on_grid)
    restitution = restitution_line(result.events, ball)
    if restitution:
        print(f"  restitution {restitution}")
    print(f"  final state h = {result.h[-1]:.12g} m, v = {result.v[-1]:.6g} m/s at t = {result.t[-1]:g} s")
    stats = result.stats
    first_use = first_use_note(stats.first_use_time, stats.engine)
    print(f"  wall time   {stats.wall_time * 1e3:.2f} ms ({stats.steps} steps, {stats.rhs_calls} "
          "right-hand-side calls)")
    if first_use:
        print(f"  first use   {first_use}")
    if stats.engine:
        print(f"  engine      {stats.engine} ({stats.engine_reason})")
    if result.error_estimate is not None:
        print(f"  error estimate             {result.error_estimate:.3e} m (the run's own, without the exact solution)")
    if accuracy is not None:
        print(f"  max |h - h_exact|          {accuracy.max_height_error:.3e} m")
        print(f"  max event time error       {accuracy.max_event_time_error:.3e} s")
    if csv_stream is not None:
        print_solution_csv(result, csv_stream)
        print("  wrote time,h,v to stdout")
    elif args.output:
        print(f"  wrote {write_solution_csv(result, args.output)}")
    if args.events:
        print(f"  wrote {write_events_csv(result, args.events)}")
    if args.plot:
        from .plotting import plot_height

        title = f"scene {scene.name}: {result.solver}, {plural(len(result.events), 'event')}"
        print(f"  wrote {plot_height(result, args.plot, title, exact=exact, t_range=plot_range)}")
    return 0


def _print_events(result, exact, exact_on_grid) -> None:
    """The events line, the first and last events, how they differ from the exact ones and why, the rest."""
    from .accuracy import max_height_error
    from .run_report import event_counts, event_differences, event_lines

    print(f"  events      {event_counts(result.events)}"
          + ("" if exact is result or exact is None else f"; exact solution: {len(exact.events)}"))
    for line in event_lines(result.events):
        print(f"              {line}")
    if exact_on_grid is not None:
        # Events match within the time the ball moves by the run's own height error.
        tolerance = max_height_error(result.h, exact_on_grid.h)
        for number, line in enumerate(event_differences(result, exact_on_grid.solution, tolerance)):
            print(f"  {'' if number else 'differences':11s} {line}")
    rest = "none" if result.rest_time is None else f"at rest from t = {result.rest_time:.12g} s"
    print(f"  rest        {rest}")


@contextlib.contextmanager
def _progress_bar(t_end: float):
    """A callback that shows the simulated time on a tqdm bar on stderr, or None: no terminal or no tqdm.

    The bar appears once the run has taken PROGRESS_AFTER seconds, and is cleared at its end.
    """
    from importlib.util import find_spec

    if not (sys.stderr.isatty() and find_spec("tqdm")):
        yield None
        return
    from tqdm import tqdm

    with tqdm(total=t_end, unit="s", desc="simulated time", delay=PROGRESS_AFTER, leave=False,
              file=sys.stderr, bar_format="{desc}: {n:.4g}/{total:.4g} s {bar} [{elapsed}<{remaining}]") as bar:
        yield lambda t: bar.update(t - bar.n)


def _check(args: argparse.Namespace) -> int:
    from .testing import check_result

    start_values = {}
    for item in args.start_value:
        name, equals, value = item.partition("=")
        if not (equals and name.strip() and value.strip()):
            raise ValueError(f"--start-value {item!r} is not allowed: it must be NAME=VALUE, for example g=1.62")
        start_values[name.strip()] = value.strip()
    outcome = check_result(args.result, args.scene, start_values, args.tolerance, args.start_time,
                           args.instance, args.input_file, args.step_size)
    print(outcome.report())
    return 0 if outcome.passed else EXIT_CHECK_FAILED


def _scenes() -> int:
    from .scenes import BUILTIN_SCENES, load_scene

    header = f"{'scene':14s}{'m [kg]':>9s}{'k [N/m]':>9s}{'b [N s/m]':>11s}{'R [m]':>7s}{'g [m/s2]':>10s}" \
             f"{'h0 [m]':>10s}{'v0 [m/s]':>10s}{'t_end [s]':>11s}  description"
    print(header)
    print("-" * len(header))
    for name in BUILTIN_SCENES:
        s = load_scene(name)
        b = s.ball
        print(f"{name:14s}{b.m:9.3g}{b.k:9.3g}{b.b:11.3g}{b.R:7.3g}{b.g:10.3g}{s.h0:10.4g}{s.v0:10.3g}"
              f"{s.t_end:11.4g}  {s.description}")
    return 0


def _parse(argv: Sequence[str] | None) -> argparse.Namespace:
    """The arguments; an unknown option is refused by its command's parser, with the option it may have meant."""
    parser = _build_parser()
    args, unknown = parser.parse_known_args(argv)
    if unknown:
        command = parser.commands[args.command]
        known = [option for action in command._actions for option in action.option_strings]
        meant = [difflib.get_close_matches(word.split("=")[0], known, n=1) for word in unknown if word.startswith("-")]
        hint = "".join(f" (did you mean {match[0]}?)" for match in meant if match)
        command.error(f"unrecognized arguments: {' '.join(unknown)}{hint}")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = _parse(argv)
    try:
        code = _command(args)
        sys.stdout.flush()  # here, where a closed pipe can still be told apart from a failure
        return code
    except BrokenPipeError:
        # `bouncingball run --output - | head`: the reader has what it wanted. Python would report the
        # pipe again when it flushes stdout at exit, so stdout goes to /dev/null from here on.
        with contextlib.suppress(OSError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_BROKEN_PIPE
    except ImportError as error:
        extra = EXTRA_OF_MODULE.get((error.name or "").split(".")[0])
        hint = f" (pip install 'bouncingball[{extra}]')" if extra and "pip install" not in str(error) else ""
        print(f"bouncingball: error: {error}{hint}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except ValueError as error:
        print(f"bouncingball: error: {error}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("bouncingball: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except RuntimeError as error:  # a solver that failed says why
        print(f"bouncingball: solver failed: {error}", file=sys.stderr)
        return EXIT_SOLVER_FAILED


def _command(args: argparse.Namespace) -> int:
    if args.command == "run":
        return _run(args)
    if args.command == "build-fmu":
        from .fmu.build import build_command

        return build_command(args.output, args.fmi_version)
    if args.command == "validate":
        from .fmu.validate import validate_command

        return validate_command(args.scene, args.fmu, args.skip, args.time_cap, args.fmi_version)
    if args.command == "check":
        return _check(args)
    if args.command == "bench":
        from .bench import bench_command

        return bench_command(args.output_dir, args.quick, args.stability, args.first_use,
                             hunt_crossley=args.hunt_crossley)
    if args.command == "sweep":
        from .sweep.command import sweep_command

        return sweep_command(args)
    return _scenes()


if __name__ == "__main__":
    sys.exit(main())
