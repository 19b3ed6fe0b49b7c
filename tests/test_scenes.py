import pytest

from bouncingball.physics import Ball
from bouncingball.scenes import BUILTIN_SCENES, load_scene

REQUIRED = ("article", "stiff", "stiff-rest", "overdamped", "tiny-mass", "undamped", "high-drop", "in-contact",
            "zero-gravity")


def test_required_scenes_are_built_in():
    assert set(REQUIRED) <= set(BUILTIN_SCENES)


@pytest.mark.parametrize("name, expected", [
    ("article", dict(ball=Ball(), h0=2.0, v0=0.0, t_end=8.0)),
    ("stiff", dict(ball=Ball(k=1e12), h0=2.0, t_end=8.0)),
    ("stiff-rest", dict(ball=Ball(k=1e12), h0=0.06 - 9.81 / 1e12, v0=0.0)),
    ("overdamped", dict(ball=Ball(b=1e4))),
    ("tiny-mass", dict(ball=Ball(m=1e-6))),
    ("undamped", dict(ball=Ball(b=0.0), t_end=1000.0)),
    ("high-drop", dict(h0=1e4, t_end=200.0)),
    ("in-contact", dict(h0=0.05)),
    ("zero-gravity", dict(ball=Ball(g=0.0), v0=-1.0)),
])
def test_builtin_scene_values(name, expected):
    scene = load_scene(name)
    for field, value in expected.items():
        assert getattr(scene, field) == value, field


def test_toml_file_holds_only_the_differences(tmp_path):
    path = tmp_path / "soft.toml"
    path.write_text('description = "a soft ball"\nk = 2.5e3\nh0 = 1.0\nt_end = 3.0\n')
    scene = load_scene(path)
    assert scene.name == "soft"
    assert scene.ball == Ball(k=2.5e3)
    assert (scene.h0, scene.v0, scene.t_end, scene.output_interval) == (1.0, 0.0, 3.0, 1e-3)
    result = scene.simulate(solver="exact")
    assert result.t[-1] == 3.0


def test_rest_height_keyword(tmp_path):
    path = tmp_path / "rest.toml"
    path.write_text('h0 = "rest"\nm = 2.0\n')
    assert load_scene(path).h0 == Ball(m=2.0).rest_height()


@pytest.mark.parametrize("text, fragment", [
    ("mass = 2.0\n", "scene key 'mass' (= 2.0) in scene 'bad' is not allowed: the keys are description, m, k"),
    ("m = -2.0\n", "m = -2.0 kg is not allowed: it must be finite and > 0"),
    ("t_end = 0\n", "t_end = 0 s is not allowed: it must be finite and > 0"),
    ("output_interval = 10.0\n", "output_interval = 10.0 s is not allowed: it must be in (0, 8]"),
    ("h0 = nan\n", "h0 = nan m is not allowed"),
    ("k = [\n", "is not valid TOML"),
])
def test_bad_scene_files(tmp_path, text, fragment):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ValueError) as info:
        load_scene(path)
    assert fragment in str(info.value)


def test_unknown_scene_lists_the_built_in_ones():
    with pytest.raises(ValueError, match="scene = 'moon' is not allowed: it must be a built-in scene .*article"):
        load_scene("moon")
