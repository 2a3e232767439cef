"""
One sphere against Hertz's closed form
======================================

A paraboloid (R = 10 mm) pressed 0.1 mm into a half-space (E = 10 MPa, nu = 0.5): the
computed pressure along a line through the tip against Hertz's
:math:`p(r) = p_0 \\sqrt{1 - r^2/a^2}`, and the load against :math:`\\tfrac43 E^* R^{1/2} d^{3/2}`.
"""

import matplotlib.pyplot as plt
import numpy as np

import twoscale
from twoscale.analytic import hertz

mat = twoscale.Material(E=10.0, nu=0.5)
R, d = 10.0, 0.1
res = twoscale.solve([[0.0, 0.0, R]], material=mat, penetration=d, shape="paraboloid")
W = hertz.load(R, d, mat.E_star)
print(f"load {res.total_load:.5g} N, Hertz {W:.5g} N, relative difference {res.total_load / W - 1:.2e}")

# %%
# The pressure on the row of cells through the tip, against the closed form.
field = res.fields[0]
X, Y = field.grid.centres()
row = np.argmin(np.abs(Y[:, 0]))
r = np.linspace(X.min(), X.max(), 400)
fig, ax = plt.subplots(figsize=(6, 3.6), layout="constrained")
ax.plot(X[row], field.pressure[row], "o", ms=3, label="twoscale (cells)")
ax.plot(r, hertz.pressure(np.abs(r), R, d, mat.E_star), "-", lw=1, label="Hertz")
ax.set(xlabel="x (mm)", ylabel="pressure (MPa)", title="one sphere on the half-space, d = 0.1 mm")
ax.legend()
plt.show()
