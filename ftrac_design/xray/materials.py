"""Linear attenuation coefficients of the fiducial's and the patient's materials at an effective energy.

Mass attenuation coefficients μ/ρ (cm²/g, total with coherent scattering) of the elements
from the NIST tables of Hubbell & Seltzer (NIST Standard Reference Database 126, "X-Ray Mass
Attenuation Coefficients", Table 3; the same numbers XCOM gives), at 40, 50, 60, 80 and
100 keV, interpolated log–log in energy. Compounds by the mixture rule
μ/ρ = Σ wᵢ (μ/ρ)ᵢ over the mass fractions wᵢ.

=========  ===========================  ====================================  ==========  ==============  ===========
material         model / source                        ρ (g/cm³)   μ/ρ 60 keV      μ 60 keV
===============  ====================================  ==========  ==============  ===========
soft_tissue      Tissue, Soft (ICRU-44), NIST Table 4  1.06        0.2048          0.0217 /mm
muscle           Muscle, Skeletal (ICRU-44)            1.05        0.2048          0.0215 /mm
adipose          Adipose Tissue (ICRU-44)              0.95        0.1974          0.0188 /mm
lung             Lung Tissue (ICRU-44) composition at  0.26        0.2053          0.0053 /mm
                 ICRU 46's healthy inflated-lung
                 density (its air weighs nothing)
cortical_bone    Bone, Cortical (ICRU-44)              1.92        0.3148          0.0604 /mm
trabecular_bone  cortical bone and red marrow (soft    1.18        0.2298          0.0271 /mm
                 tissue) mixed to ICRU 46's spongiosa
                 density 1.18: bone volume fraction
                 (1.18 − 1.06)/(1.92 − 1.06) = 14 %
air              Air, Dry (near sea level)             0.001205    0.1875          2.3e-5 /mm
titanium         Ti, NIST Table 3 (Z = 22); ρ of the   4.51        0.7661          0.346 /mm
                 metal (CRC Handbook 4.506)
===============  ====================================  ==========  ==============  ===========

``bone`` (above, built from its main elements) stays as it was for the existing anatomy
background; ``cortical_bone`` is the tabulated ICRU-44 value (1.5 % higher at 60 keV).
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

#: μ/ρ (cm²/g) of tabulated materials at ENERGIES_KEV (NIST SRD 126, Table 3 for Ti, Table 4 for the
#: ICRU-44 tissues and air) and the density (g/cm³) used with them
_TABULATED: dict[str, tuple[float, list[float]]] = {
    "soft_tissue": (1.06, [0.2688, 0.2264, 0.2048, 0.1823, 0.1693]),
    "muscle": (1.05, [0.2685, 0.2262, 0.2048, 0.1823, 0.1693]),
    "adipose": (0.95, [0.2396, 0.2123, 0.1974, 0.1800, 0.1688]),
    # the tissue's composition at the density of inflated lung (ICRU-44 lists 1.05 for the tissue alone)
    "lung": (0.26, [0.2699, 0.2270, 0.2053, 0.1826, 0.1695]),
    "cortical_bone": (1.92, [0.6655, 0.4242, 0.3148, 0.2229, 0.1855]),
    "air": (0.001205, [0.2485, 0.2080, 0.1875, 0.1662, 0.1541]),
    "titanium": (4.51, [2.214, 1.213, 0.7661, 0.4052, 0.2721]),
}

#: spongiosa as a mass mixture of cortical bone and marrow (taken as soft tissue) at ICRU 46's
#: density 1.18 g/cm³: bone volume fraction f = (1.18 − 1.06) / (1.92 − 1.06), mass fraction f·1.92/1.18
_TRABECULAR_DENSITY = 1.18
_TRABECULAR_BONE_MASS = (_TRABECULAR_DENSITY - 1.06) / (1.92 - 1.06) * 1.92 / _TRABECULAR_DENSITY

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

#: every material name :func:`linear_attenuation` knows
KNOWN = tuple(MATERIALS) + tuple(_TABULATED) + ("trabecular_bone",)

#: words in a design's material string → our material name (the more specific words first)
_ALIASES = (
    ("steel", "steel"),
    ("440c", "steel"),
    ("iron", "steel"),
    ("acetal", "acetal"),
    ("pom", "acetal"),
    ("delrin", "acetal"),
    ("pla", "pla"),
    ("water", "water"),
    ("cortical", "cortical_bone"),
    ("trabecular", "trabecular_bone"),
    ("cancellous", "trabecular_bone"),
    ("spongiosa", "trabecular_bone"),
    ("bone", "bone"),
    ("soft tissue", "soft_tissue"),
    ("muscle", "muscle"),
    ("adipose", "adipose"),
    ("fat", "adipose"),
    ("lung", "lung"),
    ("titanium", "titanium"),
    ("air", "air"),
)


def material_name(text: str) -> str:
    """Our material name for a design's free-text material ("acetal (POM-C)" → "acetal");
    ValueError naming the known materials if nothing matches."""
    low = text.lower()
    if low in KNOWN:
        return low
    for word, name in _ALIASES:
        if word in low:
            return name
    raise ValueError(f"a known material ({', '.join(KNOWN)}), got {text!r}")


def mass_attenuation(material: str, energy_kev: float) -> float:
    """μ/ρ (cm²/g) of ``material`` at ``energy_kev`` (40–100 keV), log–log interpolated."""
    if not 40.0 <= energy_kev <= 100.0:
        raise ValueError(f"an effective energy in 40–100 keV, got {energy_kev!r}")
    name = material_name(material)
    le = np.log(energy_kev)
    if name == "trabecular_bone":
        w = _TRABECULAR_BONE_MASS
        return w * mass_attenuation("cortical_bone", energy_kev) + (1 - w) * mass_attenuation("soft_tissue", energy_kev)
    if name in _TABULATED:
        return float(np.exp(np.interp(le, np.log(ENERGIES_KEV), np.log(_TABULATED[name][1]))))
    _, fractions = MATERIALS[name]
    total = 0.0
    for el, w in fractions.items():
        total += w * float(np.exp(np.interp(le, np.log(ENERGIES_KEV), np.log(_ELEMENT_MU_RHO[el]))))
    return total


def linear_attenuation(material: str, energy_kev: float = 60.0) -> float:
    """μ (1/mm) of ``material`` at ``energy_kev``: μ/ρ × ρ, converted from 1/cm."""
    return mass_attenuation(material, energy_kev) * density(material) / 10.0


def density(material: str) -> float:
    """ρ (g/cm³) of ``material`` as used for its μ (see the module's table)."""
    name = material_name(material)
    if name == "trabecular_bone":
        return _TRABECULAR_DENSITY
    if name in _TABULATED:
        return _TABULATED[name][0]
    return MATERIALS[name][0]
