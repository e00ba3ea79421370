"""Reports on the renderer's numerics (an outer layer: may import from anywhere in the package).

* :mod:`.accuracy` — error against run time (work-precision) of every model,
  tick rate and table setting, with scipy ``solve_ivp`` peers;
* :mod:`.stability` — stiff and extreme parameter sweeps with a verdict per case;
* :mod:`.peers` — the scipy peers (stick/slip switching by event functions);
* :mod:`.common` — event matching, error measures, timing, JSON, progress, plots.
"""
