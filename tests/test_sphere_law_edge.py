"""The exact sphere law's inversion stops at the sphere's edge: a load past what the cap can
carry (met by the macro step's safe path, which tries large forces) takes a few Newton steps,
not the hundred of its budget, and gives the edge's penetration."""

import numpy as np

import twoscale.laws.hertz as hertz_laws
from twoscale.laws.hertz import SphereLaw


def test_load_past_the_cap_stops_at_the_edge(monkeypatch):
    law = SphereLaw(R=np.array([9.3, 2.0]), E_star=22.4)
    calls = []
    load = hertz_laws._sphere_load
    monkeypatch.setattr(hertz_laws, "_sphere_load", lambda R, a, E: calls.append(1) or load(R, a, E))
    P = np.array([2.2e6, 1.0])  # far past the cap of R 9.3 mm at E* 22 MPa; an ordinary load
    d = law.penetration(P)
    assert len(calls) < 20
    assert np.all(np.isfinite(d)) and d[0] > 9.3  # the edge: a = R (1 - 1e-15), delta = a atanh(a/R)
    np.testing.assert_allclose(SphereLaw(R=2.0, E_star=22.4).force(d[1:]), [1.0], rtol=1e-10)
