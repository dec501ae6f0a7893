"""Notebook-style example of the Python API: a lane change, a gain sweep, a metric against the gain.

Run it as a script (`python examples/lane_change_gain_sweep.py [OUT_DIR]`) or cell by
cell in Jupyter/VS Code (the `# %%` markers). Each run is a short lane change (20 s,
through the start of the manoeuvre) in one process; the figure goes to
OUT_DIR/max_abs_yc_vs_ke.png (default runs/gain_sweep). tests/docs/test_examples.py
runs this file.
"""

# %% Setup
import sys
from pathlib import Path

import cosim

OUT = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("runs/gain_sweep")
DURATION = 20.0  # s: the lane change starts at about 13 s

# %% One lane change, as shipped (the adaptive backstepping controller)
run = cosim.run("lane_change", set={"duration": DURATION}, out=OUT / "nominal")
print(run.status, "max |yc| =", run.metrics["max_abs_yc"], "m")
signals = run.signals                      # DataFrame: index time (s), columns component.signal
print(signals[["vehicle.vx", "controller.yc"]].describe())
print("unit of vehicle.vx:", signals.attrs["units"]["vehicle.vx"])

# %% Sweep the lateral gain ke of the backstepping law
gains = [2.0, 4.0, 8.0]
max_yc = []
for ke in gains:
    swept = cosim.run("lane_change", out=OUT / f"ke_{ke:g}",
                      set={"duration": DURATION, "components.controller.parameters.ke": ke})
    max_yc.append(swept.metrics["max_abs_yc"])
    print(f"ke = {ke:g}: max |yc| = {max_yc[-1]:.4f} m")

# %% The metric against the gain
from matplotlib.figure import Figure  # noqa: E402 - a notebook cell imports what it draws with

fig = Figure(figsize=(5, 3.5), layout="constrained")
ax = fig.add_subplot()
ax.plot(gains, max_yc, "o-")
ax.set_xlabel("ke, lateral gain of the backstepping law")
ax.set_ylabel("max |yc| (m)")
ax.set_title(f"lane change, first {DURATION:g} s")
ax.grid(True, alpha=0.3)
figure_path = OUT / "max_abs_yc_vs_ke.png"
fig.savefig(figure_path, dpi=100)
print("figure:", figure_path)
