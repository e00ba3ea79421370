"""Pad and friction models by name, and the table-free pad simulator.

``MODELS`` maps a name to a model class, the way ``scipy.integrate.solve_ivp``
maps ``method`` names to ``OdeSolver`` classes. A model class only validates
and packs its parameters (a :data:`~.layouts.PAD_PARAMS` record, the C
engine's ``sd_pad_params_t``); its tick is the C engine's (``sd_model_tick``,
the model id is the position in :data:`MODELS`): ``sd_exact.c``,
``sd_pad.c`` (jump), ``sd_karnopp.c``, ``sd_stribeck.c`` and
``sd_baselines.c`` (euler, rk4, tanh: the deliberately naive integrators the
reports compare against). The
:class:`~shapedisplay.render.renderer.Renderer` owns the bookkeeping
(state, counters, buffers, checks); :func:`run_kernel` runs a model alone
over per-tick inputs.

==========  ==================================================================
name        model
==========  ==================================================================
exact       Konyo 1-DOF pad, every stick and slip phase solved in closed form,
            events located inside the tick by root finding (the reference)
jump        quasi-static O(1)-per-tick model: stick is a spring stretch,
            breakaway a threshold crossing, re-stick from the closed-form
            damped overshoot (error stated in :class:`JumpModel`)
karnopp     modified Karnopp virtual spring with velocity threshold
            (Provancher & Sylvester), drives a skin-stretch output
stribeck    Imaizumi pad with Stribeck friction on a laterally vibrating
            contactor, exponential substeps with stick/slip logic
euler       one explicit Euler step per tick (diverges on the Konyo pad)
rk4         one classical RK4 step per tick (diverges below ~45 kHz)
tanh        Konyo pad with tanh-regularised Coulomb friction (no stick state;
            creeps below breakaway; converges to ``exact`` as eps -> 0)
==========  ==================================================================
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from shapedisplay.table.devices import BurstParams, DeviceProfile, FrictionParams, PadParams, check_tick_rate, load_device
from shapedisplay.errors import InputError, ModelError, unknown_key
from shapedisplay.units import parse_quantity
from shapedisplay.render.layouts import PAD_PARAMS, PAD_STATE, record


def _extra_q(device: DeviceProfile, section: str, key: str, unit: str, default: float, bare_ok=False) -> float:
    sec = device.extra.get(section, {}) or {}
    if key not in sec:
        return default
    return parse_quantity(sec[key], unit, f"{section}.{key}", bare_ok=bare_ok)


class PadModel:
    """Base class: validated parameters packed for the C engine's ticks.

    Subclasses set ``name``, ``needs`` (table channels the model cannot run
    without) and may extend :meth:`pack`. The model id is the position in
    :data:`MODELS` (the C engine's ``SD_MODEL_*``).
    """

    name = "base"
    needs: tuple = ()      # N comes from ``normal_force`` or, if not stored, the header's constant
    #: True if the pad mass/stiffness/damping of the device are used.
    uses_pad = True

    def __init__(self, device: DeviceProfile | None = None, **options):
        self.device = (device or load_device(None))
        self.device.friction.validate()
        self.device.burst.validate()
        if self.uses_pad:
            self.device.pad.validate()
        if options:
            raise InputError(f"model '{self.name}' takes no options (got {sorted(options)})")
        #: The parameters in a one-element PAD_PARAMS array (the C engine's sd_pad_params_t) and its record.
        self.param_block = np.array([self.pack()], dtype=PAD_PARAMS)
        self.params = self.param_block[0]

    @functools.cached_property
    def _fresh_state(self) -> np.void:
        """The record of :meth:`new_state`, made once (what :func:`run_kernel` starts from by default)."""
        return self.new_state()[0]

    @functools.cached_property
    def model_id(self) -> int:
        """Position in :data:`MODELS` (``SD_MODEL_*`` in C)."""
        return MODEL_IDS[self.name]

    def pack(self) -> np.void:
        """Parameters for the kernel: a :data:`~.layouts.PAD_PARAMS` record."""
        d = self.device
        return record(PAD_PARAMS, mass=d.pad.mass, stiffness=d.pad.stiffness, damping=d.pad.damping,
                      burst_gain=d.burst.gain, max_stick_period=d.burst.max_stick_period_s, substep=1.0)[0]

    def new_state(self) -> np.ndarray:
        """A fresh state (one-element :data:`~.layouts.PAD_STATE` array): stuck, spring relaxed."""
        return record(PAD_STATE, s=1.0)

    def __repr__(self) -> str:
        return f"{type(self).__name__}(device={self.device.name!r})"


class ExactModel(PadModel):
    """Event-driven exact solution of the Konyo pad (closed-form phases, events located inside the tick).

    Stick phases are linear in time (breakaway solved exactly), slip phases
    are closed-form damped oscillations under constant kinetic friction;
    re-stick is located by bracketing between the closed-form extrema of the
    pad velocity and Newton polishing. Results do not depend on the tick
    rate (event times agree to ~1e-12 s between 1 and 10 kHz).
    """

    name = "exact"


class JumpModel(PadModel):
    """Quasi-static jump model: O(1) work per tick, O(1) per event.

    Stick: the spring stretches with the surface, ``f = k x + c V``;
    breakaway is the exact threshold crossing (linear in time). Slip is not
    integrated: the pad jumps to the re-stick stretch given by the closed-form
    damped overshoot evaluated at ``t_pi = pi / omega_d`` plus one Newton
    correction for the pad velocity ``V`` (``sd_pad.c``); for
    ``V -> 0``::

        f_restick = mu_k N - (mu_s - mu_k) N exp(-zeta pi / sqrt(1 - zeta^2))

    and the friction holds ``mu_k N`` for the slip duration. N and V are
    frozen at their breakaway values during the slip.

    Error against ``exact`` (constant V, N; measured over zeta 0..0.6,
    V 5..500 mm/s, N 0.5..5 N, checked by ``tests/test_runtime_pads.py``):
    the only approximation is the Newton step, whose error grows with the
    dimensionless pad speed ``r = V k / (delta_mu N omega_n)`` (surface speed
    over the slip-velocity amplitude). The relative stick-slip period error
    is at most ``0.02 r`` for ``r <= 0.25`` and ``zeta <= 0.6`` (measured:
    1e-3 at r = 0.22, 3e-5 at r = 0.056, 4e-8 on the published pad at
    N = 2 N, delta_mu = 0.2, V = 50 mm/s where r = 0.006), and in every
    tested case ``jump`` predicts re-stick when, and only when, ``exact``
    does (no re-stick for
    over-damped pads, for delta_mu = 0 with c > 0, or when the overshoot
    cannot bring the pad back to the surface speed: steady sliding).
    Event times inherit the period error cumulatively; changes of N or V
    during a slip (~70 us) are ignored.
    """

    name = "jump"
    #: Stated bound: relative period error <= BOUND_PER_R * r for r <= BOUND_R_MAX, zeta <= BOUND_ZETA_MAX.
    BOUND_PER_R = 0.02
    BOUND_R_MAX = 0.25
    BOUND_ZETA_MAX = 0.6


class KarnoppModel(PadModel):
    """Modified Karnopp virtual spring with skin stretch (Provancher and Sylvester).

    A spring ``k_K`` (``[karnopp] spring``, default 1.5 N/mm) anchored at
    first contact; stuck while ``k_K z <= mu_s N``; beyond, the force drops
    to ``mu_k N`` and the anchor is dragged; stuck again (force preserved)
    when the finger speed falls below ``v_T`` (``[karnopp]
    velocity_threshold``, default 12.5 mm/s); a reversal unstretches the
    spring first. ``mu_k`` comes from the profile (0.9 mu_s in the study).
    """

    name = "karnopp"
    uses_pad = False

    def pack(self) -> np.ndarray:
        P = super().pack()
        kk = _extra_q(self.device, "karnopp", "spring", "N/m", 1500.0)
        vt = _extra_q(self.device, "karnopp", "velocity_threshold", "m/s", 0.0125)
        if not kk > 0:
            raise ModelError(f"karnopp `spring` must be > 0 (got {kk} N/m)")
        if not vt >= 0:
            raise ModelError(f"karnopp `velocity_threshold` must be >= 0 (got {vt} m/s)")
        P["karnopp_spring"] = kk
        P["karnopp_v_threshold"] = vt
        return P


#: Shortest slip substep the Stribeck integrator resolves, s (a pad needing less is refused).
MIN_SUBSTEP_S = 1e-9
#: Local error allowed per Stribeck slip step, relative to the pad's scales (stretch ``mu_s W / k``, speed
#: ``|V| + A omega + mu_s W / sqrt(k m)``): the default, and the range ``[stribeck] tolerance`` or the
#: ``tolerance`` option may set. From 3e-9 up (``sd_stribeck.c``) the slip runs by exponential
#: Rosenbrock steps, below it by Taylor steps.
STRIBECK_TOLERANCE = 1e-13
STRIBECK_TOLERANCE_RANGE = (1e-14, 1e-3)


def _check_tolerance(tol, name: str) -> float:
    """The Stribeck slip tolerance as a float, or an error naming ``name``, the range and the value."""
    lo, hi = STRIBECK_TOLERANCE_RANGE
    try:
        ok = isinstance(tol, (int, float)) and not isinstance(tol, bool) and lo <= tol <= hi
    except TypeError:
        ok = False
    if not ok:
        raise InputError(f"{name} must be a number from {lo:g} to {hi:g} (got {tol!r})")
    return float(tol)


class StribeckModel(PadModel):
    """Imaizumi fingerpad with Stribeck friction on a vibrating contactor (Imaizumi et al.).

    Parameters come from the profile: ``[pad]`` (m, k, c), ``[friction]``
    (mu_s, mu_k), ``[stribeck] a, b`` (defaults 55, 1.9; the pre-maximum
    variant uses ``p = 400, d = 0.005, a = 86, b = 2.0`` unless given),
    ``[contactor] frequency, amplitude`` (default still). The finger bone
    moves at the cursor speed; the load W is the table's normal force.

    Options
    -------
    variant : {"stribeck", "premax"}
    contactor_hz, contactor_amplitude_m : float, optional
        Override the contactor stimulus.
    tolerance : float, optional
        Plain curve: the local error allowed per slip step, relative to the
        pad's scales (default :data:`STRIBECK_TOLERANCE`, 1e-13, or the
        profile's ``[stribeck] tolerance``; from 1e-14 to 1e-3). Tolerances
        from 3e-9 up run the slip by exponential Rosenbrock steps (the pad's
        fast modes in closed form, steps as long as the accuracy allows),
        tighter ones by Taylor steps of adaptive order.
    substep_s : float, optional
        Largest integration step, s. Plain curve: the slip steps are as long
        as the tolerance allows (on the negative slope the self-excitation
        shortens them by itself); default no limit beyond the tick. Pre-maximum variant: fixed exponential substeps (default 2 us),
        further limited to ``0.5 m / |c + W dmu/dv|`` where the negative
        friction slope self-excites the pad (``W dmu/dv < -c``): 1.4 us on the
        Imaizumi pad (m = 1e-4 kg), 55 ns on the 1e-6 kg Konyo pad. The model
        runs faster than real time on both (``benchmarks/bench_accuracy.py``
        prints the figure).
    """

    name = "stribeck"

    def __init__(self, device=None, variant="stribeck", contactor_hz=None, contactor_amplitude_m=None,
                 substep_s=None, tolerance=None):
        if variant not in ("stribeck", "premax"):
            raise unknown_key("stribeck variant", variant, ("stribeck", "premax"))
        if tolerance is not None:
            _check_tolerance(tolerance, "`tolerance`")
        self._tol_opt = tolerance
        self.variant = variant
        self._chz = contactor_hz
        self._camp = contactor_amplitude_m
        if substep_s is None:
            substep_s = 2e-6 if variant == "premax" else math.inf
        elif not (substep_s > 0 and math.isfinite(substep_s)):
            raise InputError(f"`substep_s` must be > 0 (got {substep_s!r})")
        self._hsub = float(substep_s)
        super().__init__(device)

    def pack(self) -> np.ndarray:
        P = super().pack()
        d = self.device
        pre = self.variant == "premax"
        if pre:   # published pre-maximum variant; [stribeck] a, b describe the plain curve
            P["stribeck_a"], P["stribeck_b"] = 86.0, 2.0
        else:
            P["stribeck_a"] = _extra_q(d, "stribeck", "a", "1", 55.0, True)
            P["stribeck_b"] = _extra_q(d, "stribeck", "b", "1", 1.9, True)
        P["stribeck_p"] = _extra_q(d, "stribeck", "p", "1", 400.0, True)
        P["stribeck_d"] = _extra_q(d, "stribeck", "d", "1", 0.005, True)
        P["stribeck_variant"] = 1 if pre else 0
        tol = self._tol_opt
        if tol is None:
            tol = _check_tolerance(_extra_q(d, "stribeck", "tolerance", "1", STRIBECK_TOLERANCE, True),
                                   "stribeck `tolerance`")
        P["stribeck_tol"] = tol
        hz = self._chz if self._chz is not None else _extra_q(d, "contactor", "frequency", "Hz", 0.0)
        amp = self._camp if self._camp is not None else _extra_q(d, "contactor", "amplitude", "m", 0.0)
        if not (hz >= 0 and amp >= 0 and math.isfinite(hz) and math.isfinite(amp)):
            raise InputError(f"contactor frequency and amplitude must be >= 0 (got {hz} Hz, {amp} m)")
        P["contactor_amplitude"] = amp
        P["contactor_omega"] = 2 * math.pi * hz
        P["substep"] = self._hsub
        self._check_resolvable(P["stribeck_a"], P["stribeck_b"])
        return P

    def _check_resolvable(self, a: float, b: float) -> None:
        """Refuse a pad whose self-excitation no substep the kernel takes can resolve.

        On the negative Stribeck slope the slip step is limited to
        ``0.5 m / (W |dmu/dv| - c)``; the steepest slope is at zero relative
        speed, ``W |dmu/dv| = (mu_s - mu_k) a - b`` whatever the load. Below
        :data:`MIN_SUBSTEP_S` the step would round to nothing (the pad's mass
        is too small for its friction curve) and the result would be NaN.
        """
        pad, fr = self.device.pad, self.device.friction
        growth = (fr.mu_s - fr.mu_k) * a - b - pad.damping     # N*s/m of negative damping, at most
        if growth > 0 and 0.5 * pad.mass / growth < MIN_SUBSTEP_S:
            raise ModelError(
                f"model 'stribeck' cannot resolve this pad: its friction slope self-excites it with a time "
                f"constant of {pad.mass / growth:.3g} s (pad mass {pad.mass:g} kg against "
                f"{growth:.3g} N*s/m of negative damping), below the {2 * MIN_SUBSTEP_S:g} s the integrator "
                f"resolves; use a pad mass >= {2 * MIN_SUBSTEP_S * growth:.3g} kg or model 'exact'")


class TanhModel(PadModel):
    """Konyo pad with tanh-regularised Coulomb friction (an option to compare against ``exact``).

    No stick state: the sign function is replaced by a smooth friction law
    (``sd_baselines.c``) peaking at ``mu_s N`` at slip speed ``eps``
    and falling to ``mu_k N``, integrated by linearly implicit exponential
    substeps. Its costs, shown by ``tests/test_runtime_pads.py``: creep below
    breakaway (the pad slips at ``|w| < eps`` while "stuck", so the spring
    stretches more slowly than ``V t``), a very stiff friction slope
    ``mu_k N / (eps / 10)`` that forces substeps, and stick-slip periods that
    converge to ``exact`` only as ``eps -> 0`` (measured on the published pad
    at 50 mm/s, 2 N: relative period error 5.5e-3 at eps = 1 mm/s, 8e-4 at
    0.1 mm/s, 8e-5 at 0.01 mm/s with 0.1 us substeps; the first breakaway
    comes late by the creep). Event times are located to the substep
    (interpolated), independent of the tick rate.

    Options
    -------
    eps_m_s : float
        Regularisation width, m/s (default 1e-4).
    substep_s : float
        Largest substep, s (default 1 us).
    """

    name = "tanh"

    def __init__(self, device=None, eps_m_s=1e-4, substep_s=1e-6):
        for name, val in (("eps_m_s", eps_m_s), ("substep_s", substep_s)):
            if not (isinstance(val, (int, float)) and math.isfinite(val) and val > 0):
                raise InputError(f"tanh model `{name}` must be > 0 (got {val!r})")
        self._eps = float(eps_m_s)
        self._hsub = float(substep_s)
        super().__init__(device)

    def pack(self) -> np.ndarray:
        P = super().pack()
        P["tanh_eps"] = self._eps
        P["substep"] = self._hsub
        return P


class EulerModel(PadModel):
    """Forward Euler, one step per tick. Diverges on the Konyo pad unless h < 2 zeta/omega_n (~5 us)."""

    name = "euler"


class Rk4Model(PadModel):
    """Classical RK4, one step per tick. Diverges on the Konyo pad unless h < 2.8/omega_n (~63 us)."""

    name = "rk4"


#: Registry: model name -> class. A new model is one class plus one line here (append: the
#: position is the model id, shared with C); then ``make generate`` (see :mod:`shapedisplay.render`).
MODELS: dict[str, type[PadModel]] = {
    "exact": ExactModel,
    "jump": JumpModel,
    "karnopp": KarnoppModel,
    "stribeck": StribeckModel,
    "euler": EulerModel,
    "rk4": Rk4Model,
    "tanh": TanhModel,
}
#: Model ids: position in :data:`MODELS`.
MODEL_IDS = {name: i for i, name in enumerate(MODELS)}


def get_model(model, device: DeviceProfile | None = None, **options) -> PadModel:
    """Instantiate ``model`` (a name, a :class:`PadModel` subclass or instance)."""
    if isinstance(model, PadModel):
        return model
    if isinstance(model, type) and issubclass(model, PadModel):
        return model(device, **options)
    if model not in MODELS:
        raise unknown_key("model", str(model), MODELS)
    return MODELS[model](device, **options)


# ================================================================ pad without a table
@dataclass(frozen=True)
class PadResult:
    """Output of :func:`simulate_pad` (all arrays float64 unless stated).

    Attributes
    ----------
    t : ndarray (n,)
        Tick end times, s.
    x : ndarray (n,)
        Pad displacement (spring stretch), m, at each tick end.
    v : ndarray (n,)
        Pad velocity, m/s, at each tick end.
    friction_force : ndarray (n,)
        Friction force on the pad, N.
    state : ndarray (n,), int8
        0 stick, 1 slip.
    event_time, event_amplitude : ndarray (n_events,)
        Stick-to-slip times (s) and burst amplitudes ``B |k x|`` at breakaway.
    model : str
    tick_rate : float
    diverged_at : float or None
        Time the explicit baselines blew up, s (None otherwise).
    """

    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    friction_force: np.ndarray
    state: np.ndarray
    event_time: np.ndarray
    event_amplitude: np.ndarray
    model: str
    tick_rate: float
    diverged_at: float | None = None


def run_kernel(model: PadModel, t, V, N, mus, muk, gain, state=None):
    """Run ``model``'s C tick over per-tick inputs (``sd_pad_run``; no table, no bursts).

    Tick ``i`` runs from ``t[i-1]`` to ``t[i]`` with the inputs ``V[i]`` (m/s), ``N[i]`` (N), ``mus[i]``,
    ``muk[i]`` and ``gain[i]`` (tick 0 has zero length and reports the initial state); ``mus``, ``muk`` and
    ``gain`` may also hold one value for every tick (shape (1,)). ``state`` (optional) is the initial
    :data:`~.layouts.PAD_STATE` (record or one-element array; default :meth:`PadModel.new_state`).

    Returns ``(state, friction, phase, x, v, ev_t, ev_a)``: the final state record, then per tick the
    friction force on the pad (N), the phase (0 stick, 1 slip), the stretch (m) and the pad velocity (m/s)
    at the tick's end (rows of one float64 block), and the stick-to-slip events (times s, burst amplitudes).
    A model that diverges (the explicit baselines) says so in ``state["diverged"]``; one that reaches its
    cap on phase changes in a tick raises :class:`ModelError`.
    """
    from shapedisplay.render.native import RUN_UNKNOWN_MODEL, library
    if _PAD_RUN is None:
        _bind_pad_run(library())
    n = int(np.shape(t)[0])
    rows = [np.ascontiguousarray(a, dtype=np.float64) for a in (t, V, N, mus, muk, gain)]
    for name, a in zip(("t", "V", "N"), rows[:3]):
        if a.shape != (n,):
            raise InputError(f"`{name}` must have shape ({n},) (got {a.shape})")
    for name, a in zip(("mus", "muk", "gain"), rows[3:]):
        if a.shape not in ((n,), (1,)) or (a.shape == (1,) and n == 0):
            raise InputError(f"`{name}` must have shape ({n},) or (1,) (got {a.shape})")
    init = model._fresh_state if state is None else np.array(state, dtype=PAD_STATE).reshape(1)[0]
    words = PAD_STATE.itemsize // 8
    cap = n // 8 + 1024
    while True:
        # one block: the final state, four per-tick rows, then the event times and amplitudes
        block = np.empty(words + 4 * n + 2 * cap)
        S = block[:words].view(PAD_STATE)
        S[0] = init
        n_ev = _PAD_RUN(model.model_id, model.param_block, S, *rows, block[words:words + 4 * n],
                        block[words + 4 * n:])
        if n_ev == RUN_UNKNOWN_MODEL:
            raise ModelError(f"the C engine has no tick for model '{model.name}' (id {model.model_id})")
        if n_ev <= cap:
            break
        cap = int(n_ev) + 64
    st = S[0]
    if st["truncated"] > 0:
        raise ModelError(f"model '{model.name}' reached its cap on phase changes in one tick "
                         f"({int(st['truncated'])} ticks cut); inputs are outside the model's range")
    rows_out = block[words:words + 4 * n].reshape(4, n)
    events = block[words + 4 * n:].reshape(2, cap)
    return st, rows_out[0], rows_out[1], rows_out[2], rows_out[3], events[0, :n_ev], events[1, :n_ev]


#: ``shapedisplay._engine.pad_run`` once bound (:func:`_bind_pad_run`).
_PAD_RUN = None


def _bind_pad_run(lib) -> None:
    """Bind the engine module's ``pad_run`` (after :func:`~.native.library` has checked the engine is current:
    the module is the same file). One call from Python without ctypes' argument conversions: a short run's
    cost is mostly its call."""
    global _PAD_RUN
    from shapedisplay import _engine
    _PAD_RUN = _engine.pad_run


def _as_ticks(value, n, field):
    a = np.asarray(value, dtype=np.float64)
    if a.ndim == 0:
        a = np.full(n, float(a))
    if a.shape != (n,):
        raise InputError(f"`{field}` must be a scalar or have shape ({n},) (got {a.shape})")
    if not np.all(np.isfinite(a)):
        raise InputError(f"`{field}` must be finite (got a non-finite value)")
    return a


def simulate_pad(model="exact", V=0.05, N=2.0, pad: PadParams | None = None,
                 friction: FrictionParams | None = None, tick_rate: float = 10_000.0,
                 duration: float = 0.1, burst: BurstParams | None = None, on_divergence="raise",
                 **options) -> PadResult:
    """Run a pad model with no table at all (e.g. the Konyo pad at constant speed).

    Parameters
    ----------
    model : str or PadModel
        A name from :data:`MODELS`.
    V : float or ndarray (n,)
        Surface velocity relative to the finger per tick, m/s.
    N : float or ndarray (n,)
        Normal force per tick, N (must be >= 0).
    pad, friction, burst : dataclasses from :mod:`shapedisplay.table.devices`
        Defaults: the published Konyo pad (k = 2 N/mm, m = 1e-6 kg,
        c = 0.01 N s/m), mu_s 0.5, mu_k 0.3, burst gain 1.
    tick_rate : float
        Hz, 100 Hz .. 192 kHz.
    duration : float
        s; the run has ``n = round(duration * tick_rate) + 1`` ticks, tick 0
        at t = 0 (array inputs fix ``n`` instead).
    on_divergence : {"raise", "report"}
        What to do when an explicit baseline blows up: raise
        :class:`ModelError`, or return the result with ``diverged_at`` set
        (outputs frozen at zero from that tick; never NaN).

    Returns
    -------
    PadResult
    """
    rate = check_tick_rate(tick_rate)
    dev = load_device(None)
    dev = dev.with_(pad=pad or dev.pad, friction=friction or dev.friction,
                    burst=burst or BurstParams(gain=1.0))
    m = get_model(model, dev, **options)
    Va = np.asarray(V, dtype=np.float64)
    Na = np.asarray(N, dtype=np.float64)
    if Va.ndim == 1:
        n = Va.shape[0]
    elif Na.ndim == 1:
        n = Na.shape[0]
    else:
        if not (math.isfinite(duration) and duration > 0):
            raise InputError(f"`duration` must be > 0 s (got {duration!r})")
        n = int(round(duration * rate)) + 1
    Va = _as_ticks(Va, n, "V")
    Na = _as_ticks(Na, n, "N")
    if np.any(Na < 0):
        raise InputError(f"`N` must be >= 0 N (got min {Na.min()})")
    t = np.arange(n, dtype=np.float64) / rate
    S, f, st, x, v, et, ea = run_kernel(m, t, Va, Na, np.array([dev.friction.mu_s]), np.array([dev.friction.mu_k]),
                                        np.ones(1))
    div = None
    if S["diverged"] != 0:
        div = float(S["diverged_at"])
        if on_divergence == "raise":
            raise ModelError(divergence_message(m, rate, div))
    return PadResult(t, x, v, f, st.astype(np.int8), et, ea, m.name, rate, div)


def divergence_message(model: PadModel, rate: float, when: float) -> str:
    p = model.device.pad
    return (f"model '{model.name}' diverged at t={when:.6g} s: tick {1e6 / rate:.4g} us is too long for the "
            f"pad (h*omega_n = {p.omega_n / rate:.3g}, zeta = {p.zeta:.3g}); use model 'exact' or 'jump'")
