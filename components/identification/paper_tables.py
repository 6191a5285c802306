"""Table 1 of the paper: hyperbolic parameters identified per test condition (paper units).

Units: k0 [N/mm], c0 [N*s/mm], alpha [N], beta [1/mm]. Keys are
(frequency [Hz], amplitude [mm], current [A]). The paper gives no F0 values.
"""

from __future__ import annotations

FREQUENCIES_HZ: tuple[float, ...] = (1.0, 2.0, 4.0)
AMPLITUDES_MM: tuple[float, ...] = (2.0, 4.0, 8.0)
CURRENTS_A: tuple[float, ...] = (0.0, 1.0, 2.0, 3.0)
PARAMS: tuple[str, ...] = ("k0", "c0", "alpha", "beta")

# (frequency, amplitude) -> parameter -> values at 0, 1, 2, 3 A, as printed in Table 1.
_TABLE1_ROWS: dict[tuple[float, float], dict[str, tuple[float, float, float, float]]] = {
    (1.0, 2.0): {
        "k0": (4.0958, 8.2243, 13.1275, 23.2931),
        "c0": (0.3537, 2.1711, 3.7312, 4.2844),
        "alpha": (14.7934, 15.2078, 26.4769, 29.0083),
        "beta": (0.0622, 0.8185, 0.8817, 0.8720),
    },
    (1.0, 4.0): {
        "k0": (2.9999, 7.8168, 11.8441, 19.0549),
        "c0": (0.3329, 1.5603, 2.5673, 3.0085),
        "alpha": (4.4035, 12.5352, 29.8296, 23.7437),
        "beta": (0.3036, 0.5271, 0.4771, 0.5692),
    },
    (1.0, 8.0): {
        "k0": (2.3289, 2.7041, 1.4534, 15.0109),
        "c0": (0.3062, 1.1810, 1.9238, 2.2723),
        "alpha": (14.4578, 24.4383, 22.1404, 21.4932),
        "beta": (0.1292, 0.2838, 0.3889, 0.3532),
    },
    (2.0, 2.0): {
        "k0": (1.6444, 18.4213, 19.0493, 27.9731),
        "c0": (0.2258, 1.1576, 1.9599, 2.2876),
        "alpha": (8.8277, 23.8813, 13.6024, 24.0823),
        "beta": (0.4337, 0.2823, 1.1128, 0.8684),
    },
    (2.0, 4.0): {
        "k0": (2.6855, 10.6519, 14.9709, 16.5911),
        "c0": (0.2127, 0.8358, 1.3552, 1.5876),
        "alpha": (11.8971, 2.8526, 17.5807, 39.0569),
        "beta": (0.2063, 0.8528, 0.5698, 0.4494),
    },
    (2.0, 8.0): {
        "k0": (1.6707, 9.8401, 7.3621, 13.9311),
        "c0": (0.1956, 0.6410, 1.0154, 1.2077),
        "alpha": (8.0351, 1.8535, 19.7717, 19.0687),
        "beta": (0.2562, 0.5285, 0.3659, 0.3742),
    },
    (4.0, 2.0): {
        "k0": (2.7132, 16.3818, 21.0926, 39.5461),
        "c0": (0.1464, 0.6477, 1.0629, 1.2206),
        "alpha": (5.5715, 3.7949, 31.8038, 2.8777),
        "beta": (0.6492, 1.2273, 0.6403, 1.7722),
    },
    (4.0, 4.0): {
        "k0": (5.3159, 14.9349, 17.1666, 27.2481),
        "c0": (0.1384, 0.4726, 0.7372, 0.8559),
        "alpha": (5.0829, 8.9217, 6.6962, 7.7418),
        "beta": (0.2159, 0.3741, 0.7907, 0.7415),
    },
    (4.0, 8.0): {
        "k0": (5.4541, 5.1195, 7.7478, 12.4571),
        "c0": (0.1277, 0.3664, 0.5604, 0.6561),
        "alpha": (2.8212, 8.6349, 21.7603, 30.5025),
        "beta": (0.1833, 0.3952, 0.3472, 0.3169),
    },
}

Condition = tuple[float, float, float]  # (frequency Hz, amplitude mm, current A)

TABLE1: dict[Condition, dict[str, float]] = {
    (f, a, i): {p: row[p][k] for p in PARAMS}
    for (f, a), row in _TABLE1_ROWS.items()
    for k, i in enumerate(CURRENTS_A)
}
"""(frequency Hz, amplitude mm, current A) -> {k0, c0, alpha, beta} in paper units."""

TEST_MATRIX: tuple[Condition, ...] = tuple(
    (f, a, i) for f in FREQUENCIES_HZ for a in AMPLITUDES_MM for i in CURRENTS_A
)
