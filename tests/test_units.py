"""Unit conversion (frictionuq.units) against the exact definitions of the units."""
from __future__ import annotations

import numpy as np
import pytest

from frictionuq import units

# exact by definition: international inch (1959), avoirdupois pound-force (0.45359237 kg x
# 9.80665 m/s^2), kip = 1000 lbf, psi = lbf/in^2
KNOWN = [
    ("displacement", "in", 0.0254),
    ("displacement", "mm", 1e-3),
    ("displacement", "m", 1.0),
    ("time", "ms", 1e-3),
    ("time", "s", 1.0),
    ("force", "N", 1.0),
    ("force", "kN", 1e3),
    ("force", "lbf", 4.4482216152605),
    ("force", "kip", 4448.2216152605),
    ("applied", "N", 1.0),
    ("applied", "kN", 1e3),
    ("applied", "lbf", 4.4482216152605),
    ("applied", "kip", 4448.2216152605),
    ("applied", "psi", 6894.757293168361),
]


@pytest.mark.parametrize("kind,unit,si", KNOWN)
def test_known_factors(kind, unit, si):
    assert units.factor(kind, unit) == pytest.approx(si, rel=1e-14)
    assert units.to_si(1.0, kind, unit) == pytest.approx(si, rel=1e-14)
    assert units.from_si(si, kind, unit) == pytest.approx(1.0, rel=1e-14)


def test_lbf_from_its_definition():
    assert units.factor("force", "lbf") == pytest.approx(0.45359237 * 9.80665, rel=1e-15)
    assert units.factor("applied", "psi") == pytest.approx(0.45359237 * 9.80665 / 0.0254**2, rel=1e-14)


def test_derived_units_are_consistent():
    # kip/in = 1000 lbf / in; lbf s/in; in/s
    assert units.factor("stiffness", "kip/in") == pytest.approx(4448.2216152605 / 0.0254, rel=1e-14)
    assert units.factor("damping", "lbf s/in") == pytest.approx(4.4482216152605 / 0.0254, rel=1e-14)
    assert units.factor("velocity", "in/s") == pytest.approx(0.0254, rel=1e-14)
    assert units.factor("acceleration", "g") == 9.80665


def test_values_of_the_seed_papers():
    # MFD: 1 in amplitude, 0.341e-3 kip/psi at 1000 psi
    assert units.to_si(1.0, "displacement", "in") == pytest.approx(0.0254)
    assert units.to_si(0.341, "force", "kip") == pytest.approx(1516.84357, rel=1e-8)
    assert units.to_si(25.4, "displacement", "mm") == pytest.approx(0.0254)
    assert units.to_si(1500.0, "time", "ms") == pytest.approx(1.5)


@pytest.mark.parametrize("kind", sorted(units.UNITS))
def test_round_trip(kind):
    rng = np.random.default_rng(0)
    v = rng.normal(0, 1e3, 50)
    for unit in units.UNITS[kind]:
        back = units.from_si(units.to_si(v, kind, unit), kind, unit)
        np.testing.assert_allclose(back, v, rtol=1e-14)
        # scalars, arrays and lists alike
        assert units.from_si(units.to_si(2.5, kind, unit), kind, unit) == pytest.approx(2.5, rel=1e-15)
        np.testing.assert_allclose(units.to_si([1.0, 2.0], kind, unit),
                                   np.array([1.0, 2.0]) * units.factor(kind, unit))


def test_si_units_have_factor_one():
    for kind, unit in units.SI.items():
        assert units.factor(kind, unit) == 1.0


def test_unknown_unit_names_unit_and_kind():
    with pytest.raises(ValueError) as exc:
        units.to_si(1.0, "displacement", "furlong")
    msg = str(exc.value)
    assert "furlong" in msg and "displacement" in msg
    # and lists what is known
    assert "mm" in msg and "in" in msg
    with pytest.raises(ValueError) as exc:
        units.from_si(1.0, "force", "kgf")
    assert "kgf" in str(exc.value) and "force" in str(exc.value)


def test_unit_of_another_kind_is_refused():
    with pytest.raises(ValueError, match="psi"):
        units.to_si(1.0, "force", "psi")       # a pressure is not a force
    with pytest.raises(ValueError, match="'ms'"):
        units.factor("displacement", "ms")


def test_unknown_kind():
    with pytest.raises(ValueError) as exc:
        units.factor("temperature", "K")
    assert "temperature" in str(exc.value)


def test_applied_si_unit():
    assert units.si_unit_of_applied("psi") == "Pa"
    assert units.si_unit_of_applied("kip") == "N"
    with pytest.raises(ValueError, match="bar"):
        units.si_unit_of_applied("bar")
