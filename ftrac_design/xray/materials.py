"""Linear attenuation coefficients of the fiducial's materials at an effective energy.

Mass attenuation coefficients μ/ρ (cm²/g, total with coherent scattering) of the elements
from the NIST tables of Hubbell & Seltzer (NIST Standard Reference Database 126, "X-Ray Mass
Attenuation Coefficients", Table 3; the same numbers XCOM gives), at 40, 50, 60, 80 and
100 keV, interpolated log–log in energy. Compounds by the mixture rule
μ/ρ = Σ wᵢ (μ/ρ)ᵢ over the mass fractions wᵢ.

=========  ==========================  ==========  =========================  ================
material   model                       ρ (g/cm³)   μ/ρ at 60 keV (cm²/g)      μ at 60 keV
=========  ==========================  ==========  =========================  ================
steel      iron (Fe)                   7.90        1.205                      0.952 /mm (9.5 /cm)
acetal     POM, (CH₂O)ₙ                1.41        0.1936                     0.0273 /mm (0.27 /cm)
pla        PLA, (C₃H₄O₂)ₙ              1.24        0.1906                     0.0236 /mm
water      H₂O                         1.00        0.2059                     0.0206 /mm
bone       cortical bone (approx.)     1.92        0.3100                     0.0595 /mm
=========  ==========================  ==========  =========================  ================

Issue 12 quotes μ_steel ≈ 9.4 /cm and μ_POM ≈ 0.27 /cm at 60 keV: iron's 1.205 cm²/g at
ρ 7.8–7.9 g/cm³ gives 9.4–9.5 /cm, and POM from the elements gives 0.273 /cm, so both agree.
Stainless steel is modelled as iron: the chromium (18 %) and nickel (8 %) of AISI 304/440C
change μ/ρ by a few per cent at 60 keV. A polychromatic beam is represented by one
effective energy (no beam hardening) — the usual simplification for a thin fiducial.
"""

from __future__ import annotations

import numpy as np

#: table energies, keV
ENERGIES_KEV = np.array([40.0, 50.0, 60.0, 80.0, 100.0])

#: μ/ρ (cm²/g) of the elements at ENERGIES_KEV (NIST SRD 126, Table 3)
_ELEMENT_MU_RHO = {
    "H": [0.3458, 0.3355, 0.3260, 0.3091, 0.2944],
    "C": [0.2076, 0.1871, 0.1753, 0.1610, 0.1514],
    "O": [0.2585, 0.2132, 0.1907, 0.1678, 0.1551],
    "Ca": [1.830, 1.019, 0.6451, 0.3500, 0.2489],
    "P": [0.7043, 0.4204, 0.2998, 0.2040, 0.1697],
    "Fe": [3.629, 1.958, 1.205, 0.5952, 0.3717],
}

_ATOMIC_MASS = {"H": 1.008, "C": 12.011, "O": 15.999, "Ca": 40.078, "P": 30.974, "Fe": 55.845}


def _by_formula(counts: dict[str, float]) -> dict[str, float]:
    mass = sum(n * _ATOMIC_MASS[e] for e, n in counts.items())
    return {e: n * _ATOMIC_MASS[e] / mass for e, n in counts.items()}


#: material name → (density g/cm³, mass fractions)
MATERIALS: dict[str, tuple[float, dict[str, float]]] = {
    "steel": (7.90, {"Fe": 1.0}),
    "acetal": (1.41, _by_formula({"C": 1, "H": 2, "O": 1})),
    "pla": (1.24, _by_formula({"C": 3, "H": 4, "O": 2})),
    "water": (1.00, _by_formula({"H": 2, "O": 1})),
    # cortical bone reduced to its main constituents (ICRU 44 fractions, N etc. lumped into O)
    "bone": (1.92, {"H": 0.034, "C": 0.155, "O": 0.475, "P": 0.103, "Ca": 0.225 + 0.008}),
}

#: words in a design's material string → our material name
_ALIASES = (("steel", "steel"), ("440c", "steel"), ("iron", "steel"), ("acetal", "acetal"), ("pom", "acetal"),
            ("delrin", "acetal"), ("pla", "pla"), ("water", "water"), ("bone", "bone"))


def material_name(text: str) -> str:
    """Our material name for a design's free-text material ("acetal (POM-C)" → "acetal");
    ValueError naming the known materials if nothing matches."""
    low = text.lower()
    if low in MATERIALS:
        return low
    for word, name in _ALIASES:
        if word in low:
            return name
    raise ValueError(f"a known material ({', '.join(MATERIALS)}), got {text!r}")


def mass_attenuation(material: str, energy_kev: float) -> float:
    """μ/ρ (cm²/g) of ``material`` at ``energy_kev`` (40–100 keV), log–log interpolated."""
    if not 40.0 <= energy_kev <= 100.0:
        raise ValueError(f"an effective energy in 40–100 keV, got {energy_kev!r}")
    _, fractions = MATERIALS[material_name(material)]
    le = np.log(energy_kev)
    total = 0.0
    for el, w in fractions.items():
        total += w * float(np.exp(np.interp(le, np.log(ENERGIES_KEV), np.log(_ELEMENT_MU_RHO[el]))))
    return total


def linear_attenuation(material: str, energy_kev: float = 60.0) -> float:
    """μ (1/mm) of ``material`` at ``energy_kev``: μ/ρ × ρ, converted from 1/cm."""
    rho, _ = MATERIALS[material_name(material)]
    return mass_attenuation(material, energy_kev) * rho / 10.0
