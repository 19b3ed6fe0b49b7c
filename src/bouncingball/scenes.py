"""Named scenarios: built-in ones, and TOML files that hold only what differs from the defaults."""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from . import limits, validation
from .contact_laws import CONTACT_PARAMETERS
from .physics import Ball
from .solvers.result import DEFAULT_OUTPUT_INTERVAL

BALL_KEYS = ("m", "k", "b", "R", "g")  # the ball's parameters that the FMU shares
# The contact law and its parameters (physics.Ball's; contact_laws.LAW_PARAMETERS says which law reads which); the FMU
# calls contact contact_law.
LAW_KEYS = ("contact", *(name for name in CONTACT_PARAMETERS if name not in BALL_KEYS))
SCENE_DEFAULTS = {"h0": 2.0, "v0": 0.0, "t_end": 8.0, "output_interval": DEFAULT_OUTPUT_INTERVAL, "F_ext": 0.0}
ALLOWED_KEYS = ("description", *BALL_KEYS, *LAW_KEYS, *SCENE_DEFAULTS)
REST = "rest"


@dataclass(frozen=True)
class Scene:
    """A ball, its initial state (h0 [m], v0 [m/s]), the duration t_end [s], the output interval [s] and F_ext [N]."""

    name: str
    description: str
    ball: Ball
    h0: float
    v0: float
    t_end: float
    output_interval: float
    F_ext: float = 0.0

    def simulate(self, solver: str = "cvode", **options):
        """Run this scene with bouncingball.simulate; t_end and output_interval may be overridden."""
        from .solvers import simulate

        t_end = options.pop("t_end", self.t_end)
        output_interval = options.pop("output_interval", min(self.output_interval, t_end))
        return simulate(self.ball, self.h0, self.v0, t_end, output_interval, solver, F_ext=self.F_ext, **options)


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
    # A scene file is refused when it is read, not when it is run, if double precision cannot resolve it.
    limits.check_scene(ball, h0, v0, F_ext, 0.0, t_end, output_interval)
    return Scene(name=name, description=str(values.get("description", "")), ball=ball, h0=h0, v0=v0, t_end=t_end,
                 output_interval=output_interval, F_ext=F_ext)


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


