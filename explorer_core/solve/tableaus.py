"""Butcher tableaus of the integrators, as data.

RK4: the classical fourth-order method. DP5: Dormand & Prince (1980), "A family of
embedded Runge-Kutta formulae", J. Comp. Appl. Math. 6, the 5(4) pair with FSAL. DOP853:
Hairer, Norsett & Wanner, Solving ODEs I (2nd ed.), II.10, the 8(5,3) pair; only the 12
stages of the step (not the dense-output stages) are kept. Values as published (and as
used by scipy.integrate, which the tests compare against). VERN9: Verner's 9(8) "most efficient"
pair (2010), checked against every order condition in the tests; at tolerances 1e-8 and below it
needs 4-17 % fewer field evaluations per period than DOP853 with 1.2-5x smaller errors at the same
tolerance (benchmarks/high_accuracy.py), so it is the method for accurate work (orbits, Lyapunov
spectra, long runs): the default method ``"auto"`` (config.DEFAULT_METHOD, :func:`resolve_method`) takes it from
rtol config.VERN9_MAX_RTOL down to config.VERN9_MIN_RTOL, where the analyses measured faster with it.
Below rtol ~1e-13 its error estimate (weights up to 2.6) picks up round-off -- most likely of the stage
times ``t + c h`` at large ``t`` (ulp(t) ~ 1e-12 after 1000 periods) -- and its steps grow with ``t``: at
1e-14, 44 -> 72 steps per period over 400 periods alone, 72 -> 286 in lock-step blocks of 32 (DOP853:
73 -> 105 over 1000). Use it at 1e-13 and above.

:data:`METHODS` holds each as a validated :class:`Method`; the engine
(:mod:`explorer_core.solve.rk`) does the arithmetic for all of them. ``taylor`` is Taylor's method
(:mod:`explorer_core.solve.taylor`): no tableau, listed here so every boundary accepts its name.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from explorer_core import config

# Classical RK4.
RK4_A = np.array(
    [
        [0.0, 0.0, 0.0, 0.0],
        [0.5, 0.0, 0.0, 0.0],
        [0.0, 0.5, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
    ]
)
RK4_B = np.array([0.16666666666666666, 0.3333333333333333, 0.3333333333333333, 0.16666666666666666])
RK4_C = np.array([0.0, 0.5, 0.5, 1.0])

# Dormand-Prince 5(4); E has 7 entries, the last for the FSAL stage f(t+h, y_new).
DP5_A = np.array(
    [
        [0.0, 0.0, 0.0, 0.0, 0.0],
        [0.2, 0.0, 0.0, 0.0, 0.0],
        [0.075, 0.225, 0.0, 0.0, 0.0],
        [0.9777777777777777, -3.7333333333333334, 3.5555555555555554, 0.0, 0.0],
        [2.9525986892242035, -11.595793324188385, 9.822892851699436, -0.2908093278463649, 0.0],
        [2.8462752525252526, -10.757575757575758, 8.906422717743473, 0.2784090909090909, -0.2735313036020583],
    ]
)
DP5_B = np.array(
    [0.09114583333333333, 0.0, 0.44923629829290207, 0.6510416666666666, -0.322376179245283, 0.13095238095238096]
)
DP5_C = np.array([0.0, 0.2, 0.3, 0.8, 0.8888888888888888, 1.0])
DP5_E = np.array(
    [
        -0.0012326388888888888,
        0.0,
        0.0042527702905061394,
        -0.03697916666666667,
        0.05086379716981132,
        -0.0419047619047619,
        0.025,
    ]
)
DP5_ORDER = 5
DP5_ERROR_ORDER = 4

# DOP853; E3, E5 have 13 entries, the last for f(t+h, y_new).
DOP853_A = np.array(
    [
        [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [0.05260015195876773, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [0.0197250569845379, 0.0591751709536137, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [0.02958758547680685, 0.0, 0.08876275643042054, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [0.2413651341592667, 0.0, -0.8845494793282861, 0.924834003261792, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [0.037037037037037035, 0.0, 0.0, 0.17082860872947386, 0.12546768756682242, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [0.037109375, 0.0, 0.0, 0.17025221101954405, 0.06021653898045596, -0.017578125, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [
            0.03709200011850479,
            0.0,
            0.0,
            0.17038392571223998,
            0.10726203044637328,
            -0.015319437748624402,
            0.008273789163814023,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
        ],
        [
            0.6241109587160757,
            0.0,
            0.0,
            -3.3608926294469414,
            -0.868219346841726,
            27.59209969944671,
            20.154067550477894,
            -43.48988418106996,
            0.0,
            0.0,
            0.0,
            0.0,
        ],
        [
            0.47766253643826434,
            0.0,
            0.0,
            -2.4881146199716677,
            -0.590290826836843,
            21.230051448181193,
            15.279233632882423,
            -33.28821096898486,
            -0.020331201708508627,
            0.0,
            0.0,
            0.0,
        ],
        [
            -0.9371424300859873,
            0.0,
            0.0,
            5.186372428844064,
            1.0914373489967295,
            -8.149787010746927,
            -18.52006565999696,
            22.739487099350505,
            2.4936055526796523,
            -3.0467644718982196,
            0.0,
            0.0,
        ],
        [
            2.273310147516538,
            0.0,
            0.0,
            -10.53449546673725,
            -2.0008720582248625,
            -17.9589318631188,
            27.94888452941996,
            -2.8589982771350235,
            -8.87285693353063,
            12.360567175794303,
            0.6433927460157636,
            0.0,
        ],
    ]
)
DOP853_B = np.array(
    [
        0.054293734116568765,
        0.0,
        0.0,
        0.0,
        0.0,
        4.450312892752409,
        1.8915178993145003,
        -5.801203960010585,
        0.3111643669578199,
        -0.1521609496625161,
        0.20136540080403034,
        0.04471061572777259,
    ]
)
DOP853_C = np.array(
    [
        0.0,
        0.05260015195876773,
        0.0789002279381516,
        0.1183503419072274,
        0.2816496580927726,
        0.3333333333333333,
        0.25,
        0.3076923076923077,
        0.6512820512820513,
        0.6,
        0.8571428571428571,
        1.0,
    ]
)
DOP853_E3 = np.array(
    [
        -0.18980075407240762,
        0.0,
        0.0,
        0.0,
        0.0,
        4.450312892752409,
        1.8915178993145003,
        -5.801203960010585,
        -0.4226823213237919,
        -0.1521609496625161,
        0.20136540080403034,
        0.02265179219836082,
        0.0,
    ]
)
DOP853_E5 = np.array(
    [
        0.01312004499419488,
        0.0,
        0.0,
        0.0,
        0.0,
        -1.2251564463762044,
        -0.4957589496572502,
        1.6643771824549864,
        -0.35032884874997366,
        0.3341791187130175,
        0.08192320648511571,
        -0.022355307863886294,
        0.0,
    ]
)
DOP853_ORDER = 8
DOP853_ERROR_ORDER = 7


# Verner's 9(8) "most efficient" pair: J. H. Verner, "Numerically optimal Runge-Kutta pairs with interpolants",
# Numer. Algorithms 53 (2010) 383-396, the 16-stage pair (its interpolant's extra stages not kept). Not FSAL: the
# engine's extra stage f(t + h, y_new) is the next step's first, so a step costs 16 evaluations. E has 17
# entries (b - b_hat on the stages; 0 on that extra stage). Decimal values as published by Verner (and as in
# OrdinaryDiffEq.jl's Vern9Tableau); tests/test_integrators.py checks every order condition through 9 (8 for
# b_hat) on them, so a wrong digit cannot pass.
VERN9_C = np.array(
    [0.0, 0.03462, 0.09702435063878045, 0.14553652595817068, 0.561, 0.22900791159048503, 0.544992088409515,
     0.645, 0.48375, 0.06757, 0.25, 0.6590650618730999, 0.8206, 0.9012, 1.0, 1.0]
)  # fmt: skip
VERN9_A = np.zeros((16, 16))
for _i, _row in enumerate(
    [
        [],
        [0.03462],
        [-0.03893354388572875, 0.13595789452450918],
        [0.03638413148954267, 0.0, 0.10915239446862801],
        [2.0257639143939694, 0.0, -7.638023836496291, 6.173259922102322],
        [0.05112275589406061, 0.0, 0.0, 0.17708237945550218, 0.0008027762409222536],
        [0.13160063579752163, 0.0, 0.0, -0.2957276252669636, 0.08781378035642955, 0.6213052975225274],
        [0.07166666666666667, 0.0, 0.0, 0.0, 0.0, 0.33055335789153195, 0.2427799754418014],
        [0.071806640625, 0.0, 0.0, 0.0, 0.0, 0.3294380283228177, 0.1165190029271823, -0.034013671875],
        [
            0.04836757646340646,
            0.0,
            0.0,
            0.0,
            0.0,
            0.03928989925676164,
            0.10547409458903446,
            -0.021438652846483126,
            -0.10412291746271944,
        ],
        [
            -0.026645614872014785,
            0.0,
            0.0,
            0.0,
            0.0,
            0.03333333333333333,
            -0.1631072244872467,
            0.03396081684127761,
            0.1572319413814626,
            0.21522674780318796,
        ],
        [
            0.03689009248708622,
            0.0,
            0.0,
            0.0,
            0.0,
            -0.1465181576725543,
            0.2242577768172024,
            0.02294405717066073,
            -0.0035850052905728597,
            0.08669223316444385,
            0.43838406519683376,
        ],
        [
            -0.4866012215113341,
            0.0,
            0.0,
            0.0,
            0.0,
            -6.304602650282853,
            -0.2812456182894729,
            -2.679019236219849,
            0.5188156639241577,
            1.3653531876033418,
            5.8850910885039465,
            2.8028087862720628,
        ],
        [
            0.4185367457753472,
            0.0,
            0.0,
            0.0,
            0.0,
            6.724547581906459,
            -0.42544428016461133,
            3.3432791530012653,
            0.6170816631175374,
            -0.9299661239399329,
            -6.099948804751011,
            -3.002206187889399,
            0.2553202529443446,
        ],
        [
            -0.7793740861228848,
            0.0,
            0.0,
            0.0,
            0.0,
            -13.937342538107776,
            1.2520488533793563,
            -14.691500408016868,
            -0.494705058533141,
            2.2429749091462368,
            13.367893803828643,
            14.396650486650687,
            -0.79758133317768,
            0.4409353709534278,
        ],
        [
            2.0580513374668867,
            0.0,
            0.0,
            0.0,
            0.0,
            22.357937727968032,
            0.9094981099755646,
            35.89110098240264,
            -3.442515027624454,
            -4.865481358036369,
            -18.909803813543427,
            -34.26354448030452,
            1.2647565216956427,
        ],
    ]
):
    VERN9_A[_i, : len(_row)] = _row
VERN9_B = np.array(
    [0.014611976858423152, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -0.3915211862331339, 0.23109325002895065,
     0.12747667699928525, 0.2246434176204158, 0.5684352689748513, 0.058258715572158275, 0.13643174034822156,
     0.030570139830827976, 0.0]
)  # fmt: skip
VERN9_E = np.array(
    [-0.005357988290444578, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -2.583020491182464, 0.14252253154686625,
     0.013420653512688676, -0.02867296291409493, 2.624999655215792, -0.2825509643291537, 0.13643174034822156,
     0.030570139830827976, -0.04834231373823958, 0.0]
)  # fmt: skip
VERN9_ORDER = 9
VERN9_ERROR_ORDER = 8


# ---------------------------------------------------------------------------
# Methods: the tableaus above, checked on construction.

#: Tolerance of the checks of a tableau's consistency conditions (the published values are rounded).
_CHECK_TOL = 1e-14


@dataclass(frozen=True)
class Method:
    """An explicit Runge-Kutta method: tableau, order and (for an embedded pair) error weights.

    ``a`` (s, s) strictly lower triangular, ``b`` and ``c`` (s,); ``e``, ``e3``, ``e5`` (s + 1,) weights of
    the error estimate on the stages and the FSAL stage ``f(t + h, y_new)``: ``e`` for a standard pair
    (DP5), ``e5`` and ``e3`` for DOP853's combined estimate (``e`` zero). Checked on construction:
    ``sum(b) = 1``, the rows of ``a`` sum to ``c``, each set of error weights sums to 0.
    """

    name: str
    order: int
    adaptive: bool
    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    error_order: int = 0
    e: np.ndarray | None = None
    e3: np.ndarray | None = None
    e5: np.ndarray | None = None
    #: ``"rk"``: the tableau above, run by the engine (:mod:`explorer_core.solve.rk`); ``"taylor"``: Taylor's
    #: method (:mod:`explorer_core.solve.taylor`), no tableau (empty ``a, b, c``), order and step from the tolerance.
    kind: str = "rk"

    def __post_init__(self) -> None:
        if self.kind not in ("rk", "taylor"):
            raise ValueError(f"method {self.name!r}: kind must be 'rk' or 'taylor', got {self.kind!r}")
        if self.kind == "taylor":
            if self.b.size or self.a.size or self.c.size or not self.adaptive:
                raise ValueError(f"method {self.name!r}: a Taylor method is adaptive and has no tableau")
            for name in ("e", "e3", "e5"):
                object.__setattr__(self, name, np.zeros(1))
            return
        s = self.b.shape[0]
        a = np.zeros((s, s))
        a[: self.a.shape[0], : self.a.shape[1]] = self.a[:s, :s]
        object.__setattr__(self, "a", a)
        zero = np.zeros(s + 1)
        for name in ("e", "e3", "e5"):
            v = getattr(self, name)
            object.__setattr__(self, name, zero.copy() if v is None else np.asarray(v, float)[: s + 1].copy())
        problems = []
        if self.c.shape != (s,):
            problems.append(f"c has shape {self.c.shape}, b has {s} stages")
        if np.any(np.triu(a) != 0.0):
            problems.append("a is not strictly lower triangular (explicit methods only)")
        if abs(self.b.sum() - 1.0) > _CHECK_TOL:
            problems.append(f"sum(b) = {self.b.sum()!r}, not 1")
        if self.c.shape == (s,) and np.abs(a.sum(axis=1) - self.c).max() > _CHECK_TOL:
            problems.append("the rows of a do not sum to c")
        for name in ("e", "e3", "e5"):
            if abs(getattr(self, name).sum()) > _CHECK_TOL:
                problems.append(f"the error weights {name} do not sum to 0")
        if self.adaptive and not (np.any(self.e) or (np.any(self.e3) and np.any(self.e5))):
            problems.append("an adaptive method needs error weights")
        if problems:
            raise ValueError(f"tableau {self.name!r}: " + "; ".join(problems))

    @property
    def stages(self) -> int:
        return self.b.shape[0]

    @property
    def dop853_error(self) -> bool:
        """True for DOP853's combined 5th/3rd-order error estimate."""
        return bool(np.any(self.e5))


METHODS: dict[str, Method] = {
    "rk4": Method("rk4", 4, False, RK4_A, RK4_B, RK4_C),
    "dp5": Method("dp5", DP5_ORDER, True, DP5_A, DP5_B, DP5_C, DP5_ERROR_ORDER, e=DP5_E),
    "dop853": Method(
        "dop853", DOP853_ORDER, True, DOP853_A, DOP853_B, DOP853_C, DOP853_ERROR_ORDER, e3=DOP853_E3, e5=DOP853_E5
    ),
    "vern9": Method("vern9", VERN9_ORDER, True, VERN9_A, VERN9_B, VERN9_C, VERN9_ERROR_ORDER, e=VERN9_E),
    # Order 0: it follows the tolerance (explorer_core.solve.taylor.taylor_order).
    "taylor": Method("taylor", 0, True, np.zeros((0, 0)), np.zeros(0), np.zeros(0), kind="taylor"),
}


#: The method name resolved by the tolerance (:func:`resolve_method`).
AUTO = "auto"


def get_method(name: str) -> Method:
    """The method called ``name``; a ValueError names the bad value and the choices."""
    try:
        return METHODS[str(name).lower()]
    except KeyError:
        raise ValueError(f"unknown method {name!r}; choose one of {AUTO}, {', '.join(METHODS)}") from None


def resolve_method(name: str, rtol: float, adaptive: bool = True) -> str:
    """The concrete method that ``name`` stands for at ``rtol``: ``"auto"`` is ``"vern9"`` where it needs less
    work than DOP853 (``config.VERN9_MIN_RTOL <= rtol <= config.VERN9_MAX_RTOL``, measured in
    benchmarks/method_choice.py) and ``"dop853"`` elsewhere and at fixed steps (``adaptive=False``); any other
    name is checked and returned as the method's own name."""
    if str(name).lower() == AUTO:
        return "vern9" if adaptive and config.VERN9_MIN_RTOL <= rtol <= config.VERN9_MAX_RTOL else "dop853"
    return get_method(name).name
