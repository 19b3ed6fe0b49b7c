"""Named scenarios: built-in ones, and TOML files that hold only what differs from the defaults."""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from . import limits, validation
from .contact_laws import CONTACT_PARAMETERS
from .ground import Ground
from .physics import Ball
from .solvers.result import DEFAULT_OUTPUT_INTERVAL

BALL_KEYS = ("m", "k", "b", "R", "g")  # the ball's parameters that the FMU shares
# The contact law and its parameters (physics.Ball's; contact_laws.LAW_PARAMETERS says which law reads which); the FMU
# calls contact contact_law.
LAW_KEYS = ("contact", *(name for name in CONTACT_PARAMETERS if name not in BALL_KEYS))
SCENE_DEFAULTS = {"h0": 2.0, "v0": 0.0, "t_end": 8.0, "output_interval": DEFAULT_OUTPUT_INTERVAL, "F_ext": 0.0}
ALLOWED_KEYS = ("description", *BALL_KEYS, *LAW_KEYS, *SCENE_DEFAULTS, "ground")
# A scene's [ground] table: a still ground's height, a sine's three, or a table's two lists; one kind at a time.
GROUND_KEYS = {"still": ("height",), "sine": ("amplitude", "frequency", "phase"), "table": ("times", "positions")}
REST = "rest"


@dataclass(frozen=True)
class Scene:
    """A ball, its start (h0 [m], v0 [m/s]), duration t_end [s], output interval [s], F_ext [N] and ground."""

    name: str
    description: str
    ball: Ball
    h0: float
    v0: float
    t_end: float
    output_interval: float
    F_ext: float = 0.0
    ground: Ground = Ground()

    def simulate(self, solver: str = "cvode", **options):
        """Run this scene with bouncingball.simulate; t_end and output_interval may be overridden."""
        from .solvers import simulate

        t_end = options.pop("t_end", self.t_end)
        output_interval = options.pop("output_interval", min(self.output_interval, t_end))
        return simulate(self.ball, self.h0, self.v0, t_end, output_interval, solver, F_ext=self.F_ext,
                        ground=self.ground, **options)


def _builtin_table() -> dict[str, dict]:
    text = resources.files(__package__).joinpath("data/scenes.toml").read_text(encoding="utf-8")
    return tomllib.loads(text)


BUILTIN_SCENES: tuple[str, ...] = tuple(_builtin_table())


def scene_from_mapping(name: str, values: dict) -> Scene:
    """Build a Scene from the keys that differ from the defaults; unknown keys are refused.

    So is a scene outside the range double precision resolves (limits.check_scene).
    """
    unknown = [key for key in values if key not in ALLOWED_KEYS]
    if unknown:
        raise ValueError(f"scene key {unknown[0]!r} (= {values[unknown[0]]!r}) in scene {name!r} is not allowed: "
                         f"the keys are {', '.join(ALLOWED_KEYS)}")
    ball = Ball(**{key: values[key] for key in (*BALL_KEYS, *LAW_KEYS) if key in values})
    merged = {**SCENE_DEFAULTS, **{key: values[key] for key in SCENE_DEFAULTS if key in values}}
    F_ext = validation.finite("F_ext", merged["F_ext"], "N")
    h0 = ball.rest_height(F_ext) if merged["h0"] == REST else validation.finite("h0", merged["h0"], "m")
    t_end = validation.positive("t_end", merged["t_end"], "s")
    v0 = validation.finite("v0", merged["v0"], "m/s")
    output_interval = validation.in_range("output_interval", merged["output_interval"], 0.0, t_end, "s")
    ground = ground_from_mapping(name, values.get("ground", {}))
    ground.check_covers(0.0, t_end)
    # A scene file is refused when it is read, not when it is run, if double precision cannot resolve it.
    limits.check_scene(ball, h0 - ground.position(0.0), v0, F_ext, 0.0, t_end, output_interval)
    return Scene(name=name, description=str(values.get("description", "")), ball=ball, h0=h0, v0=v0, t_end=t_end,
                 output_interval=output_interval, F_ext=F_ext, ground=ground)


def ground_from_mapping(name: str, values) -> Ground:
    """The Ground a scene's [ground] table describes: its keys checked as the scene's are (GROUND_KEYS).

    height: a still ground; amplitude, frequency (and phase): a vibrating table; times and positions: a
    ground through those points. No key: the still ground at 0.
    """
    if not isinstance(values, dict):
        raise ValueError(f"scene key 'ground' (= {values!r}) in scene {name!r} is not allowed: it must be a table "
                         f"([ground] with the keys of one of: "
                         + "; ".join(f"{kind}: {', '.join(keys)}" for kind, keys in GROUND_KEYS.items()) + ")")
    allowed = [key for keys in GROUND_KEYS.values() for key in keys]
    unknown = [key for key in values if key not in allowed]
    if unknown:
        raise ValueError(f"scene key 'ground.{unknown[0]}' (= {values[unknown[0]]!r}) in scene {name!r} is not "
                         f"allowed: the keys are {', '.join(allowed)}")
    kinds = [kind for kind, keys in GROUND_KEYS.items() if any(key in values for key in keys)]
    if len(kinds) > 1:
        first, second = (next(key for key in GROUND_KEYS[kind] if key in values) for kind in kinds[:2])
        raise ValueError(f"scene keys 'ground.{first}' and 'ground.{second}' in scene {name!r} are not allowed "
                         f"together: a ground is still (height), a sine (amplitude, frequency, phase) or a table "
                         f"(times, positions)")
    if not kinds:
        return Ground.still()
    if kinds[0] == "still":
        return Ground.still(values["height"])
    missing = [key for key in GROUND_KEYS[kinds[0]] if key not in values and key != "phase"]
    if missing:
        raise ValueError(f"scene key 'ground.{missing[0]}' in scene {name!r} is missing: a {kinds[0]} ground needs "
                         f"{', '.join(key for key in GROUND_KEYS[kinds[0]] if key != 'phase')}")
    if kinds[0] == "sine":
        return Ground.sine(values["amplitude"], values["frequency"], values.get("phase", 0.0))
    return Ground.table(values["times"], values["positions"])


def load_scene(name_or_path: str | Path) -> Scene:
    """A built-in scene by name, or a scene from a TOML file (top-level keys as in the built-in table)."""
    text = str(name_or_path)
    table = _builtin_table()
    if text in table:
        return scene_from_mapping(text, table[text])
    path = Path(text)
    if path.suffix.lower() == ".toml":
        if not path.is_file():
            raise ValueError(f"scene file {text!r} is not allowed: no such file")
        try:
            values = tomllib.loads(path.read_text(encoding="utf-8"))
        except tomllib.TOMLDecodeError as error:
            raise ValueError(f"scene file {text!r} is not valid TOML: {error}") from None
        except UnicodeDecodeError as error:
            raise ValueError(f"scene file {text!r} is not UTF-8 text (as TOML must be): {error}") from None
        except OSError as error:
            raise ValueError(f"scene file {text!r} cannot be read: {error.strerror or error}") from None
        return scene_from_mapping(path.stem, values)
    raise ValueError(f"scene = {text!r} is not allowed: it must be a built-in scene "
                     f"({', '.join(table)}) or a .toml file")


