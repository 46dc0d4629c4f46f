"""Energy-dependent linear attenuation μ(E) of every material the independent renderer uses.

Values are the total mass attenuation coefficients μ/ρ (cm²/g, coherent scattering
included) of J. H. Hubbell and S. M. Seltzer, *Tables of X-Ray Mass Attenuation
Coefficients and Mass Energy-Absorption Coefficients*, NIST Standard Reference Database 126
(NISTIR 5632, version 1.4, 2004; the numbers XCOM gives for these energies): Table 3 for the
elements H, C, O, Al, Fe, Cu and Table 4 for the ICRU-44 tissues, liquid water and dry air,
written out here at the table's own energies 10–150 keV (no absorption edge of these
materials lies in that range) and interpolated log–log in energy.

This table is deliberately separate from ``ftrac_design.xray.materials`` (which holds only
40–100 keV at one effective energy): the held-out renderer shares no code with the simulator
it checks.

- **steel**: stainless steel taken as iron, ρ = 7.90 g/cm³ (AISI 304 / 440C carry 17–19 %
  Cr and up to 10 % Ni, which move μ/ρ by a few per cent; the tracker must not depend on that).
- **acetal**: POM (CH₂O)ₙ, ρ = 1.41 g/cm³, from H, C, O by the mixture rule.
- **soft_tissue**, **adipose**, **bone** (cortical): ICRU-44 compositions, ρ = 1.06, 0.95,
  1.92 g/cm³.
- **water** ρ = 1.00; **air** ρ = 1.205e-3; **aluminium** ρ = 2.699; **copper** ρ = 8.96
  (the tube filters).
"""

from __future__ import annotations

import numpy as np

#: table energies, keV (NIST SRD 126 grid)
TABLE_KEV = np.array([10.0, 15.0, 20.0, 30.0, 40.0, 50.0, 60.0, 80.0, 100.0, 150.0])

#: μ/ρ (cm²/g) at TABLE_KEV, NIST SRD 126 Table 3 (elements) and Table 4 (materials)
MU_RHO = {
    "H": [0.3854, 0.3764, 0.3695, 0.3570, 0.3458, 0.3355, 0.3260, 0.3091, 0.2944, 0.2651],
    "C": [2.373, 0.8071, 0.4420, 0.2562, 0.2076, 0.1871, 0.1753, 0.1610, 0.1514, 0.1347],
    "O": [5.952, 1.836, 0.8651, 0.3779, 0.2585, 0.2132, 0.1907, 0.1678, 0.1551, 0.1361],
    "Al": [26.23, 7.955, 3.441, 1.128, 0.5685, 0.3681, 0.2778, 0.2018, 0.1704, 0.1378],
    "Fe": [170.6, 57.08, 25.68, 8.176, 3.629, 1.958, 1.205, 0.5952, 0.3717, 0.1964],
    "Cu": [215.9, 74.05, 33.79, 10.92, 4.862, 2.613, 1.593, 0.7630, 0.4584, 0.2217],
    "water": [5.329, 1.673, 0.8096, 0.3756, 0.2683, 0.2269, 0.2059, 0.1837, 0.1707, 0.1505],
    "air": [5.120, 1.614, 0.7779, 0.3538, 0.2485, 0.2080, 0.1875, 0.1662, 0.1541, 0.1356],
    "soft_tissue": [5.379, 1.699, 0.8230, 0.3790, 0.2688, 0.2264, 0.2048, 0.1823, 0.1693, 0.1492],
    "adipose": [3.268, 1.083, 0.5677, 0.3063, 0.2396, 0.2123, 0.1974, 0.1800, 0.1688, 0.1500],
    "bone": [28.51, 9.032, 4.001, 1.331, 0.6655, 0.4242, 0.3148, 0.2229, 0.1855, 0.1480],
}

_ATOMIC_MASS = {"H": 1.008, "C": 12.011, "O": 15.999}
_POM_MASS = _ATOMIC_MASS["C"] + 2 * _ATOMIC_MASS["H"] + _ATOMIC_MASS["O"]

#: material → (density g/cm³, {table entry: mass fraction})
MATERIALS: dict[str, tuple[float, dict[str, float]]] = {
    "steel": (7.90, {"Fe": 1.0}),
    "acetal": (
        1.41,
        {
            "C": _ATOMIC_MASS["C"] / _POM_MASS,
            "H": 2 * _ATOMIC_MASS["H"] / _POM_MASS,
            "O": _ATOMIC_MASS["O"] / _POM_MASS,
        },
    ),
    "water": (1.00, {"water": 1.0}),
    "air": (1.205e-3, {"air": 1.0}),
    "soft_tissue": (1.06, {"soft_tissue": 1.0}),
    "adipose": (0.95, {"adipose": 1.0}),
    "bone": (1.92, {"bone": 1.0}),
    "aluminium": (2.699, {"Al": 1.0}),
    "copper": (8.96, {"Cu": 1.0}),
}


def mass_attenuation(material: str, energy_kev: np.ndarray) -> np.ndarray:
    """μ/ρ (cm²/g) of ``material`` at ``energy_kev`` (10–150 keV), log–log interpolated.

    Parameters
    ----------
    material : str
        A key of :data:`MATERIALS`.
    energy_kev : array_like
        Photon energies, keV, within the table's 10–150 keV.

    Returns
    -------
    numpy.ndarray
        μ/ρ in cm²/g, the shape of ``energy_kev``.
    """
    if material not in MATERIALS:
        raise KeyError(f"unknown material {material!r}; known: {sorted(MATERIALS)}")
    e = np.asarray(energy_kev, float)
    if np.any(e < TABLE_KEV[0]) or np.any(e > TABLE_KEV[-1]):
        raise ValueError(f"energy outside the table's {TABLE_KEV[0]:g}–{TABLE_KEV[-1]:g} keV")
    _, fractions = MATERIALS[material]
    out = np.zeros_like(e)
    for entry, w in fractions.items():
        out += w * np.exp(np.interp(np.log(e), np.log(TABLE_KEV), np.log(MU_RHO[entry])))
    return out


def density(material: str) -> float:
    """Mass density (g/cm³) of ``material``."""
    return MATERIALS[material][0]


def linear_attenuation(material: str, energy_kev: np.ndarray) -> np.ndarray:
    """μ (1/mm) of ``material`` at ``energy_kev``: μ/ρ × ρ / 10.

    Parameters
    ----------
    material : str
        A key of :data:`MATERIALS`.
    energy_kev : array_like
        Photon energies, keV.

    Returns
    -------
    numpy.ndarray
        Linear attenuation coefficients, 1/mm.
    """
    return mass_attenuation(material, energy_kev) * density(material) / 10.0
