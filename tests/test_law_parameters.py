"""Each contact law's parameters (contact_laws.LAW_PARAMETERS), everywhere they belong.

The table is held to the code: a parameter a law does not read leaves its run bit-identical, one it reads
changes it. Another law's parameter set to a value other than Ball's default is refused by name by Ball,
the command line and scene files (the FMU's warning: test_fmu_rigid.py).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import bouncingball as bb
from bouncingball.cli import EXIT_BAD_INPUT, main
from bouncingball.contact_laws import CONTACT_LAWS, CONTACT_PARAMETERS, LAW_PARAMETERS
from bouncingball.physics import BALL_DEFAULTS

# Each parameter's value away from its default (every law's range allows it)
CHANGED = {"k": 2e4, "b": 20.0, "e": 0.5, "v_min": 2.0, "n": 2.0, "alpha": 0.1}
# A ball of each law whose run each of its own parameters changes (Hunt-Crossley damped, so alpha's change shows)
BASE = {"linear": {}, "rigid": {}, "linear-no-pull": {}, "hunt-crossley": {"k": 1e6, "alpha": 0.05}}


def _run(ball: bb.Ball):
    return bb.simulate(ball, 1.0, 0.0, 3.0, 1e-3, engine="sksundae")


def _with(ball: bb.Ball, name: str, value: float) -> bb.Ball:
    """The ball with one field changed past Ball's own check: what a run would do with a value it refused."""
    changed = dataclasses.replace(ball)
    object.__setattr__(changed, name, value)
    return changed


@pytest.mark.parametrize("law", CONTACT_LAWS)
def test_the_table_says_which_parameters_each_law_reads(law):
    assert set(LAW_PARAMETERS) == set(CONTACT_LAWS) and set(LAW_PARAMETERS[law]) <= set(CONTACT_PARAMETERS)
    ball = bb.Ball(contact=law, **BASE[law])
    reference = _run(ball)
    for name in CONTACT_PARAMETERS:
        run = _run(_with(ball, name, CHANGED[name]))
        same = np.array_equal(run.h, reference.h) and np.array_equal(run.v, reference.v) \
            and [event.time for event in run.events] == [event.time for event in reference.events]
        assert same == (name not in LAW_PARAMETERS[law]), (law, name)


@pytest.mark.parametrize("law", CONTACT_LAWS)
def test_another_laws_parameter_is_refused_by_name_and_its_default_is_not(law):
    for name in CONTACT_PARAMETERS:
        if name in LAW_PARAMETERS[law]:
            assert getattr(bb.Ball(contact=law, **{name: CHANGED[name]}), name) == CHANGED[name]
            continue
        assert bb.Ball(contact=law, **{name: BALL_DEFAULTS[name]}).contact == law  # the default means "not set"
        with pytest.raises(ValueError) as refused:
            bb.Ball(contact=law, **{name: CHANGED[name]})
        readers = ", ".join(sorted(other for other, own in LAW_PARAMETERS.items() if name in own))
        assert str(refused.value) == (
            f"{name} = {CHANGED[name]!r} is not allowed with contact = {law!r}: that law reads only "
            f"{', '.join(LAW_PARAMETERS[law])} (besides m, R and g); leave it at its default ({name} = "
            f"{BALL_DEFAULTS[name]!r}) or choose a contact law that reads it ({readers})")


def test_a_rigid_run_with_alpha_is_refused_on_the_command_line_by_its_option(capsys):
    assert main(["run", "--contact", "rigid", "--alpha", "0.3"]) == EXIT_BAD_INPUT
    [line] = capsys.readouterr().err.strip().splitlines()
    assert line.startswith("bouncingball: error: --alpha = 0.3 is not allowed with --contact = 'rigid': that law "
                           "reads only --e, --v-min"), line
    assert main(["run", "--contact", "hunt-crossley", "--e", "0.5"]) == EXIT_BAD_INPUT
    assert "--e = 0.5 is not allowed with --contact = 'hunt-crossley'" in capsys.readouterr().err


def test_a_law_from_the_command_line_drops_the_scenes_parameters_it_does_not_read(capsys):
    """`run stiff --contact rigid`: the scene's k = 1e12 was its linear law's; the run is the plain rigid ball's."""
    assert main(["run", "stiff", "--contact", "rigid", "--e", "0.8", "--t-end", "2"]) == 0
    out = capsys.readouterr().out
    expected = bb.simulate(bb.Ball(contact="rigid", e=0.8), 2.0, 0.0, 2.0)
    assert "rigid contact, e = 0.8" in out
    assert f"final state h = {expected.h[-1]:.12g} m" in out


def test_a_scene_file_takes_the_hunt_crossley_parameters(tmp_path, capsys):
    from bouncingball.scenes import load_scene

    path = tmp_path / "soft.toml"
    path.write_text('contact = "hunt-crossley"\nk = 1e6\nn = 1.5\nalpha = 0.2\nt_end = 2.0\n')
    scene = load_scene(path)
    assert (scene.ball.contact, scene.ball.k, scene.ball.n, scene.ball.alpha) == ("hunt-crossley", 1e6, 1.5, 0.2)
    direct = bb.simulate(bb.Ball(contact="hunt-crossley", k=1e6, alpha=0.2), 2.0, 0.0, 2.0)
    assert np.array_equal(scene.simulate().h, direct.h)
    assert main(["run", str(path)]) == 0
    assert "Hunt-Crossley contact, k = 1e+06 N/m^1.5, n = 1.5, alpha = 0.2 s/m" in capsys.readouterr().out


def test_a_scene_file_with_a_parameter_its_law_does_not_read_is_refused_by_name(tmp_path, capsys):
    path = tmp_path / "rigid.toml"
    path.write_text('contact = "rigid"\ne = 0.7\nalpha = 0.3\n')
    assert main(["run", str(path)]) == EXIT_BAD_INPUT
    assert "alpha = 0.3 is not allowed with contact = 'rigid': that law reads only e, v_min" in \
        capsys.readouterr().err


@pytest.mark.parametrize(("text", "version"), [("2", 2), ("2.0", 2), ("3", 3), ("3.0", 3)])
def test_fmi_version_takes_the_versions_as_fmi_writes_them(text, version):
    from bouncingball.cli import _build_parser

    for command in (["build-fmu"], ["validate"]):
        assert _build_parser().parse_args([*command, "--fmi-version", text]).fmi_version == version


def test_another_fmi_version_is_refused_naming_the_allowed_ones(capsys):
    with pytest.raises(SystemExit) as exited:
        main(["build-fmu", "--fmi-version", "2.5"])
    assert exited.value.code == 2
    assert "'2.5' is not allowed: it must be 2 (or 2.0) or 3 (or 3.0)" in capsys.readouterr().err
