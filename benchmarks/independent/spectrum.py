"""A tungsten-anode X-ray spectrum: Kramers' law, 1 keV bins, aluminium and copper filtration.

Kramers' thick-target law gives the bremsstrahlung photon number per unit energy
``dN/dE ∝ Z (E₀ − E) / E`` up to the tube voltage E₀ (kVp). Each 1 keV bin carries the
integral of that law over the bin, ``E₀ ln(E₂/E₁) − (E₂ − E₁)``, at the bin's photon-weighted
mean energy ``∫(E₀ − E) dE / ∫(E₀ − E)/E dE``, so the binned spectrum has exactly the
continuous law's mean energy. The filtration (total, inherent included) multiplies each bin
by ``exp(−μ_Al t_Al − μ_Cu t_Cu)``. Characteristic W K lines (58–67 keV, a few per cent of
the photons at 80 kVp) and the anode's self-absorption are left out.

Bins start at 10 keV, where the attenuation tables start: below that, 3 mm Al transmits
less than e⁻²¹.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .attenuation import linear_attenuation

#: lowest photon energy considered, keV
E_MIN_KEV = 10.0


@dataclass(frozen=True)
class Spectrum:
    """Photons per bin (relative, summing to 1) and the bins' mean energies (keV)."""

    kvp: float
    energy_kev: np.ndarray
    photons: np.ndarray

    @property
    def mean_energy_kev(self) -> float:
        """Photon-number-weighted mean energy, keV."""
        return float(np.sum(self.photons * self.energy_kev) / np.sum(self.photons))

    @property
    def energy_weighted_mean_kev(self) -> float:
        """Mean energy weighted by energy fluence (what an energy-integrating detector sees), keV."""
        w = self.photons * self.energy_kev
        return float(np.sum(w * self.energy_kev) / np.sum(w))


def kramers_bins(kvp: float, e_min_kev: float = E_MIN_KEV) -> tuple[np.ndarray, np.ndarray]:
    """Unfiltered Kramers spectrum in 1 keV bins from ``e_min_kev`` to ``kvp``.

    Parameters
    ----------
    kvp : float
        Tube voltage E₀, kV (the spectrum's end point in keV).
    e_min_kev : float
        Lower edge of the first bin, keV.

    Returns
    -------
    (energy_kev, photons) : tuple of numpy.ndarray
        Each bin's photon-weighted mean energy (keV) and its relative photon number
        (normalised to sum 1); the last bin may be narrower than 1 keV.
    """
    if not kvp > e_min_kev + 1:
        raise ValueError(f"kvp must exceed {e_min_kev + 1:g}, got {kvp!r}")
    edges = np.arange(e_min_kev, kvp, 1.0)
    edges = np.append(edges, kvp) if edges[-1] < kvp else edges
    e1, e2 = edges[:-1], edges[1:]
    number = kvp * np.log(e2 / e1) - (e2 - e1)
    energy_sum = kvp * (e2 - e1) - (e2**2 - e1**2) / 2
    return energy_sum / number, number / number.sum()


def kramers_mean_energy(kvp: float, e_min_kev: float = E_MIN_KEV) -> float:
    """Closed-form photon mean energy (keV) of the unfiltered Kramers law on [e_min, kvp]:
    ``(E₀ − E_min)² / 2 / (E₀ ln(E₀/E_min) − (E₀ − E_min))``."""
    d = kvp - e_min_kev
    return d * d / 2 / (kvp * np.log(kvp / e_min_kev) - d)


def tungsten_spectrum(kvp: float = 80.0, al_mm: float = 3.0, cu_mm: float = 0.1) -> Spectrum:
    """Filtered tungsten spectrum: Kramers' law × Al and Cu transmission, 1 keV bins.

    Parameters
    ----------
    kvp : float
        Tube voltage, kV (70–90 is the C-arm range this renderer is meant for; 20–150 accepted).
    al_mm, cu_mm : float
        Total aluminium and copper filtration, mm.

    Returns
    -------
    Spectrum
        Relative photon numbers per bin (sum 1) at the bins' mean energies.
    """
    if not 20.0 <= kvp <= 150.0:
        raise ValueError(f"kvp: 20–150 kV, got {kvp!r}")
    energy, photons = kramers_bins(kvp)
    trans = np.exp(-linear_attenuation("aluminium", energy) * al_mm - linear_attenuation("copper", energy) * cu_mm)
    photons = photons * trans
    keep = photons > photons.max() * 1e-9
    return Spectrum(float(kvp), energy[keep], photons[keep] / photons[keep].sum())
