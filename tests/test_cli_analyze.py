"""``uio-jax analyze``: what the text and the JSON say for a model with parameters."""

import json
import textwrap

from uio_jax import cli

SUM_ONLY = textwrap.dedent("""\
    name = "sum_only"
    description = "x' = -(a + b) x, y = x: only a + b is identifiable"
    states = ["x"]

    [params]
    a = [0.5, 1.5]
    b = [0.5, 1.5]

    [outputs]
    y = "x"

    [dynamics]
    x = "-(a + b)*x"
    """)


def test_parameter_directions_in_the_text_and_the_json(tmp_path, capsys):
    model = tmp_path / "sum_only.toml"
    model.write_text(SUM_ONLY)
    out_json = tmp_path / "r.json"
    assert cli.main(["analyze", str(model), "--samples", "64", "--no-cache", "--no-progress",
                     "--json", str(out_json)]) == 0
    out, err = capsys.readouterr()
    lines = out.splitlines()
    assert lines[2].startswith("answer: exact")
    assert "observable codistribution: dim 2 of 3 (states and parameters)" in out
    at = lines.index("unobservable directions at the centre of the domain (x=1, a=1, b=1):")
    assert lines[at + 1] == "  +0.707 a  -0.707 b"
    assert lines[at + 2] == "identifiable combination (its differential at this point): da + db"
    data = json.loads(out_json.read_text())
    (d,) = data["unobservable_directions"]
    assert d["x"] == 0.0 and abs(d["a"] - 0.5 ** 0.5) < 1e-12 and abs(d["b"] + 0.5 ** 0.5) < 1e-12
    assert data["directions_at"]["point"] == {"x": 1.0, "a": 1.0, "b": 1.0}
    assert "centre of the sampling box" in data["directions_at"]["rule"]
    assert data["identifiable"] == {"a": False, "b": False} and data["n"] == 3  # old keys kept
