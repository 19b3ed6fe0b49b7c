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

from . import AccuracyWarning
from .cli_parser import build_parser as _build_parser
from .contact_laws import LAWS
from .ground import Ground
from .output import STANDARD_OUTPUT

EXIT_BAD_INPUT = 2
EXIT_SOLVER_FAILED = 1
EXIT_CHECK_FAILED = 1  # `check`: the result is not within the tolerance of the exact solution
EXIT_INTERRUPTED = 130  # 128 + SIGINT, as shells report it
PROGRESS_AFTER = 2.0  # s: `run` shows a progress bar once it has taken this long (on a terminal, with tqdm)
EXIT_BROKEN_PIPE = 141  # 128 + SIGPIPE: the reader (`| head`) stopped reading
# The optional modules a command may need, and the extra that installs each.
EXTRA_OF_MODULE = {"fmpy": "fmu", "pythonfmu": "fmu", "docutils": "fmu", "scipy": "reference", "matplotlib": "plot",
                   "tqdm": "bench", "dask": "sweep", "distributed": "sweep", "pandas": "sweep", "pyarrow": "sweep"}


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
    from .run_report import first_use_note, lyapunov_line, plural, restitution_line
    from .scenes import load_scene

    scene = _with_ground_options(_with_law_options(load_scene(args.scene), args), args)
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
    judged = result.solver != "exact" and LAWS[scene.ball.contact].closed_form
    accuracy, exact_on_grid = accuracy_of_result(result, scene.h0, scene.v0) if judged else (None, None)
    exact = result if result.solver == "exact" else None if exact_on_grid is None else exact_on_grid.result()

    ball = scene.ball
    print(f"scene {scene.name}: {scene.description}")
    law = LAWS[ball.contact].summary.format(**dataclasses.asdict(ball))
    print(f"  ball        m = {ball.m:g} kg, {law}, R = {ball.R:g} m, g = {ball.g:g} m/s2")
    print(f"  start       h0 = {scene.h0:.15g} m, v0 = {scene.v0:g} m/s; {result.t[0]:g} to {result.t[-1]:g} s, "
          f"output every {result.t[1] - result.t[0]:g} s")
    if scene.ground != Ground():
        print(f"  ground      {scene.ground.describe()}")
    settings = ", ".join(f"{key} {value}" for key, value in result.options.items())
    print(f"  solver      {result.solver}" + (f" ({settings})" if settings else ""))
    _print_events(result, exact, exact_on_grid)
    restitution = restitution_line(result.events, ball, result.ground)
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
    if result.lyapunov is not None:
        print(f"  Lyapunov exponent          {lyapunov_line(result.lyapunov)}")
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


def _with_law_options(scene, args: argparse.Namespace):
    """The scene with the command line's contact law and its parameters (--contact, --e, --v-min, --n, --alpha ...).

    A law given with --contact keeps the scene's values of the parameters it reads and drops the others (they
    were the scene's law's); a parameter given here that the law does not read is refused by its option.
    """
    from . import validation
    from .contact_laws import CONTACT_LAWS, CONTACT_PARAMETERS, LAW_PARAMETERS
    from .physics import Ball, unread_message, unread_parameters

    given = {name: getattr(args, name) for name in CONTACT_PARAMETERS if getattr(args, name, None) is not None}
    if args.contact is None and not given:
        return scene
    ball = scene.ball
    contact = ball.contact if args.contact is None else validation.choice("--contact", args.contact, CONTACT_LAWS)
    unread = unread_parameters(contact, given)
    if unread:
        raise ValueError(unread_message(contact, unread, option="--"))
    kept = {name: getattr(ball, name) for name in LAW_PARAMETERS[contact]}
    law_ball = Ball(m=ball.m, R=ball.R, g=ball.g, contact=contact, **{**kept, **given})
    return dataclasses.replace(scene, ball=law_ball)


def _with_ground_options(scene, args: argparse.Namespace):
    """The scene on the command line's ground (--ground-amplitude, -frequency, -phase; or --ground-table)."""
    from .ground import Ground

    sine = {name: getattr(args, f"ground_{name}") for name in ("amplitude", "frequency", "phase")
            if getattr(args, f"ground_{name}") is not None}
    if sine and args.ground_table:
        raise ValueError(f"--ground-table = {args.ground_table!r} is not allowed with --ground-{next(iter(sine))}: "
                         "the ground is either a sine or a table")
    if args.ground_table:
        return dataclasses.replace(scene, ground=_ground_table(args.ground_table))
    if not sine:
        return scene
    for name in ("amplitude", "frequency"):
        if name not in sine:
            raise ValueError(f"--ground-{name} is missing: a vibrating ground needs --ground-amplitude and "
                             "--ground-frequency (and --ground-phase, 0 by default)")
    return dataclasses.replace(scene, ground=Ground.sine(sine["amplitude"], sine["frequency"], sine.get("phase", 0.0)))


def _ground_table(path: str):
    """The Ground through the points of a CSV file (time [s], height [m]; a header line allowed)."""
    import numpy as np

    from .ground import Ground

    try:
        with open(path, encoding="utf-8") as stream:
            lines = [line for line in stream.read().splitlines() if line.strip()]
    except OSError as error:
        raise ValueError(f"--ground-table = {path!r} cannot be read: {error.strerror or error}") from None
    rows = []
    for number, line in enumerate(lines, start=1):
        cells = [cell.strip() for cell in line.split(",")]
        try:
            rows.append([float(cell) for cell in cells])
        except ValueError:
            if number == 1:  # a header
                continue
            raise ValueError(f"--ground-table = {path!r} line {number} ({line!r}) is not allowed: it must be two "
                             "numbers, time [s] and height [m]") from None
        if len(cells) != 2:
            raise ValueError(f"--ground-table = {path!r} line {number} ({line!r}) is not allowed: it must be two "
                             "numbers, time [s] and height [m]")
    table = np.asarray(rows, dtype=float).reshape(-1, 2)
    return Ground.table(table[:, 0], table[:, 1])


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
    still = "at rest" if not result.ground.moves else "riding the ground for good"
    rest = "none" if result.rest_time is None else f"{still} from t = {result.rest_time:.12g} s"
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
    from .check.judge import check_result

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
    args.argv = list(sys.argv[1:] if argv is None else argv)  # as typed: `sweep` repeats it to say how to resume
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
        from .extras import install_command

        extra = EXTRA_OF_MODULE.get((error.name or "").split(".")[0])
        hint = f" ({install_command(extra)})" if extra and "pip install" not in str(error) else ""
        print(f"bouncingball: error: {error}{hint}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except ValueError as error:
        print(f"bouncingball: error: {error}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt as interrupt:  # a command that keeps work says where, and how to go on
        print("bouncingball: interrupted" + (f": {interrupt}" if str(interrupt) else ""), file=sys.stderr)
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
                             hunt_crossley=args.hunt_crossley, c_fmu=args.c_fmu)
    if args.command == "sweep":
        from .sweep.command import sweep_command

        return sweep_command(args)
    return _scenes()


if __name__ == "__main__":
    sys.exit(main())
