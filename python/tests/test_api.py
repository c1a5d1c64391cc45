"""The package's surface: version, type stubs, docstring examples, scenes."""

from __future__ import annotations

import ast
import doctest
import inspect
import pathlib
import re

import springmass
from springmass import _core

PY = pathlib.Path(__file__).resolve().parents[1]


def cargo_version(path: pathlib.Path) -> str:
    text = path.read_text()
    package = text.split("[package]", 1)[1]
    return re.search(r'^version\s*=\s*"([^"]+)"', package, re.M).group(1)


def test_version_is_the_crate_version():
    assert springmass.__version__ == cargo_version(PY.parent / "Cargo.toml")
    assert springmass.__version__ == cargo_version(PY / "Cargo.toml")


def test_stubs_match_the_native_module():
    stub = ast.parse((PY / "springmass" / "_core.pyi").read_text())
    stubbed = {f.name: f for f in stub.body if isinstance(f, ast.FunctionDef)}
    native = {name for name, v in vars(_core).items() if callable(v) and not isinstance(v, type)}
    assert set(stubbed) == native
    for name, f in stubbed.items():
        sig = inspect.signature(getattr(_core, name))
        want = [(a.arg, "positional") for a in f.args.posonlyargs + f.args.args]
        want += [(a.arg, "keyword") for a in f.args.kwonlyargs]
        got = [
            (p.name, "keyword" if p.kind is inspect.Parameter.KEYWORD_ONLY else "positional")
            for p in sig.parameters.values()
        ]
        assert got == want, name
    for cls in ("UnresolvableError", "NumericalError"):
        assert any(isinstance(c, ast.ClassDef) and c.name == cls for c in stub.body)
    assert issubclass(springmass.UnresolvableError, ValueError)
    assert issubclass(springmass.NumericalError, RuntimeError)


def test_public_functions_have_numpy_style_docstrings():
    for name in springmass.__all__:
        obj = getattr(springmass, name)
        if inspect.isfunction(obj):
            doc = inspect.getdoc(obj)
            assert doc and "Parameters\n----------" in doc and "Returns\n-------" in doc, name
            assert "Examples\n--------" in doc, name


def test_docstring_examples_run():
    res = doctest.testmod(springmass, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert res.attempted > 10 and res.failed == 0


def test_scenes_are_the_papers():
    s3 = springmass.scene("s3")
    assert (s3.n, s3.d, s3.k, s3.gamma, s3.mass) == (20, 0.1, 1.0, 1.0, 1.0)
    assert s3.defects == (springmass.Defect("mass", 8, 5.0), springmass.Defect("mass", 15, 2.0))
    assert springmass.scene("P2").chain()["defects"] == [springmass.Defect("mass", 3, 4.0)]
    try:
        springmass.scene("S9")
    except ValueError as e:
        assert e.field == "scene" and "S1" in str(e)
    else:
        raise AssertionError("S9 is not a scene")


def test_defects_in_every_form_build_the_same_chain():
    forms = [
        [("mass", 8, 5.0), ("spring", 3, 0.5)],
        [springmass.Defect("mass", 8, 5.0), springmass.Defect("spring", 3, 0.5)],
        ["mass:8:5", "spring:3:0.5"],
        [["mass", 8, 5], ("spring", 3, 0.5)],
    ]
    values = [springmass.response([0.3, 1 + 1j], n=10, defects=f) for f in forms]
    for v in values[1:]:
        assert (v == values[0]).all()
    one = springmass.response(0.3, n=10, defects=("mass", 8, 5.0))  # a single defect
    assert one == springmass.response(0.3, n=10, defects=[springmass.Defect("mass", 8, 5.0)])


def test_example_fits_a_csv(s1_record, tmp_path):
    import importlib.util
    import subprocess
    import sys

    from conftest import write_csv

    t, x = s1_record
    csv = tmp_path / "x1.csv"
    write_csv(csv, t, x)
    png = tmp_path / "fit.png"
    out = subprocess.run(
        [sys.executable, str(PY / "examples" / "fit_measured.py"), str(csv), "--n", "5", "--defects", "auto:2",
         "--plot", str(png)],
        capture_output=True,
        text=True,
    )
    assert out.returncode == 0, out.stderr
    lines = [line.split() for line in out.stdout.splitlines() if line.startswith("  mass at")]
    assert [line[2] for line in lines] == ["2:", "4:"], out.stdout
    assert png.is_file() == (importlib.util.find_spec("matplotlib") is not None)


def test_spectral_rebuilds_every_mass_from_the_modes():
    import numpy as np

    # an undamped chain n = 6, k = 2, masses m; its Jacobi matrix's spectrum
    m = np.array([1.0, 2.5, 1.0, 1.0, 0.7, 1.0])
    k = 2.0
    n = m.size
    j = np.zeros((n, n))
    for i in range(n):
        j[i, i] = 2 * k / m[i]
        if i + 1 < n:
            j[i, i + 1] = j[i + 1, i] = -k / np.sqrt(m[i] * m[i + 1])
    lam, v = np.linalg.eigh(j)
    r = springmass.spectral(np.sqrt(lam), v[0, :] ** 2 / m[0], k=k)
    assert r.resolved
    np.testing.assert_allclose(r.masses, m, rtol=1e-10)
    try:
        springmass.spectral([1.0, 2.0], [0.5], k=k)
    except ValueError as e:
        assert "residue" in str(e)
    else:
        raise AssertionError("unequal lengths accepted")


def test_fit_profile_every_mass_with_error_bars_and_named_errors():
    import numpy as np

    t = np.arange(0, 150, 0.25)
    x = springmass.simulate(8, defects=[("mass", 3, 2.0)], t=t, noise="rel:1e-3", seed=4)
    r = springmass.fit_profile(t, x, n=8)
    assert r.mode == "masses" and len(r.values) == 8
    truth = [1.0, 1.0, 2.0, 1.0, 1.0, 1.0, 1.0, 1.0]
    for v, m in zip(r.values, truth):
        assert v.kind == "mass" and v.visible
        assert abs(v.value - m) < 5 * v.se, (v, m)
    assert r.sigma_estimated and r.sigma > 0
    assert "profile of masses" in str(r)
    for kwargs, field in [({"profile": "all"}, "profile"), ({"change": 0.0}, "change")]:
        try:
            springmass.fit_profile(t, x, n=8, **kwargs)
        except ValueError as e:
            assert field in str(e), e
        else:
            raise AssertionError(f"{kwargs} accepted")
