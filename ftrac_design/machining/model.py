"""The stock, the reference cuts and the tools, as plain numbers (mm, radians, frame F).

Reference cuts are the shapes the CAD removes (:mod:`ftrac_design.manufacture.plan` builds them):

- :class:`EllipseCut` — a rectangle ``[-w/2, w/2] × [-floor_depth, top_height]`` swept along
  the seated ellipse in its surface-normal frame: ``u`` across the groove along
  ``B = T × N``, ``v`` along the outward normal ``N`` (radial). The centre-line lies on the
  cylinder of radius ``b`` at ``z(φ) = z_c − k_c cos φ − k_s sin φ``.
- :class:`SlotCut` — a box along ``z`` whose walls are parallel to the radial plane at the
  slot's azimuth and whose floor is the plane ``floor_radius`` from the axis.
- :class:`PocketCut` — a flat-bottomed radial cylinder.

Each gives the exact interval of a radial ray (azimuth θ, height z) that it removes, and a
signed distance (negative inside). Rays and the stock are what :mod:`.simulate` works on.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

#: newton iterations for the ellipse groove's normal plane through a point (quadratic
#: convergence from φ = θ; 5 reach machine precision for every preset, tests/test_machining.py)
NEWTON_STEPS = 5


@dataclass(frozen=True)
class Stock:
    """The blank: a tube about ``z``, ``outer_radius``/``bore_radius`` mm, ``|z| ≤ half_length``."""

    outer_radius: float
    bore_radius: float
    half_length: float


def box_sdf(x: np.ndarray, y: np.ndarray, hx: float, hy: float) -> np.ndarray:
    """Signed distance to the rectangle ``|x| ≤ hx, |y| ≤ hy`` (negative inside)."""
    dx, dy = np.abs(x) - hx, np.abs(y) - hy
    return np.hypot(np.maximum(dx, 0), np.maximum(dy, 0)) + np.minimum(np.maximum(dx, dy), 0)


@dataclass(frozen=True)
class EllipseCut:
    """An ellipse groove: centre-line on the cylinder ``b`` at ``z(φ) = z_c − k_c cos φ − k_s sin φ``."""

    id: str
    seat_radius: float
    z_center: float
    k_cos: float
    k_sin: float
    width: float
    floor_depth: float
    top_height: float

    @classmethod
    def from_plane(
        cls, id: str, seat_radius: float, normal, z_center: float, width: float, floor_depth: float, top_height: float
    ) -> "EllipseCut":
        """From the ellipse's plane: through ``(0, 0, z_center)`` with unit ``normal`` (F)."""
        n = np.asarray(normal, float)
        if abs(n[2]) < 1e-9:
            raise ValueError(f"ellipse {id}: its plane contains the body axis")
        b = seat_radius
        return cls(id, b, z_center, b * n[0] / n[2], b * n[1] / n[2], width, floor_depth, top_height)

    def z(self, phi):
        """Centre-line height at azimuth ``phi`` (rad)."""
        return self.z_center - self.k_cos * np.cos(phi) - self.k_sin * np.sin(phi)

    def dz(self, phi):
        """``dz/dφ`` of the centre-line."""
        return self.k_cos * np.sin(phi) - self.k_sin * np.cos(phi)

    def frame_coords(self, rho, theta, z, phi=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(φ, u, v)`` of points ``(ρ, θ, z)``: the azimuth of the normal plane through the
        point, and its coordinates across (``u``) and along the normal (``v``) in that plane.
        ``phi``: a start for the Newton iteration (default θ)."""
        rho, theta, z = np.broadcast_arrays(*(np.asarray(a, float) for a in (rho, theta, z)))
        b, kc, ks = self.seat_radius, self.k_cos, self.k_sin
        st, ct = np.sin(theta), np.cos(theta)
        phi = theta.copy() if phi is None else np.array(phi, float)
        for _ in range(NEWTON_STEPS):  # T(φ)·(p − P(φ)) = 0
            sp, cp = np.sin(phi), np.cos(phi)
            s, c = st * cp - ct * sp, ct * cp + st * sp  # sin, cos of θ − φ
            dzp = z - (self.z_center - kc * cp - ks * sp)
            d1 = kc * sp - ks * cp
            d2 = kc * cp + ks * sp
            phi = phi - (b * rho * s + d1 * dzp) / (-b * rho * c + d2 * dzp - d1 * d1)
        sp, cp = np.sin(phi), np.cos(phi)
        s, c = st * cp - ct * sp, ct * cp + st * sp
        d1 = kc * sp - ks * cp
        u = (d1 * rho * s - b * (z - (self.z_center - kc * cp - ks * sp))) / np.hypot(b, d1)
        return phi, u, rho * c - b

    def sdf(self, rho, theta, z) -> np.ndarray:
        """Signed distance (mm) in the normal plane through the point: equal to the 3-D
        distance to second order in distance × curvature (≤ 1e-5 mm within 0.05 mm)."""
        _, u, v = self.frame_coords(rho, theta, z)
        return self._box(u, v)

    def _box(self, u, v):
        mid = (self.top_height - self.floor_depth) / 2
        return box_sdf(u, v - mid, self.width / 2, (self.top_height + self.floor_depth) / 2)

    def ray_interval(self, theta, z, rho_max: float, iterations: int = 4) -> tuple[np.ndarray, np.ndarray]:
        """``(lo, hi)`` of the rays removed by the groove, NaN where a ray misses it.

        Along a ray ``v`` grows like ρ and ``u`` changes slowly and smoothly, so the floor
        (``v = −floor_depth``) and the walls (``u = ±width/2``) are each one root, found by
        secant steps from the floor and top radii (``iterations`` reach 1e-10 mm here); the
        inside set is the ρ between them, checked at its middle.
        """
        theta, z = np.broadcast_arrays(np.asarray(theta, float), np.asarray(z, float))
        b, hw = self.seat_radius, self.width / 2
        r_top = min(rho_max, b + self.top_height)

        def uv(r, phi=None):
            return self.frame_coords(r, theta, z, phi)

        def root(f, r0, r1, f0, f1):
            # secant steps kept inside the bracket [ra, rb]
            for _ in range(iterations):
                with np.errstate(divide="ignore", invalid="ignore"):
                    r2 = np.where(np.abs(f1 - f0) > 1e-15, r1 - f1 * (r1 - r0) / (f1 - f0), r1)
                r2 = np.clip(np.nan_to_num(r2, nan=ra[0]), ra, rb)
                r0, f0, r1, f1 = r1, f1, r2, f(r2)
            return r1

        ra, rb = np.full(theta.shape, b - self.floor_depth), np.full(theta.shape, r_top)
        phi_a, ua, va = uv(ra)
        _, ub, vb = uv(rb, phi_a)
        fa, fb = va + self.floor_depth, vb + self.floor_depth
        r_floor = np.where(fa >= 0, ra, root(lambda r: uv(r, phi_a)[2] + self.floor_depth, ra, rb, fa, fb))
        lo, hi = r_floor, np.full(theta.shape, r_top)
        for side in (-hw, hw):
            ga, gb = ua - side, ub - side
            crosses = (ga * gb) < 0
            cross = root(lambda r: uv(r, phi_a)[1] - side, ra, rb, ga, gb)
            # u moving toward the inside of the groove: the crossing is an entry, else an exit
            entering = (gb > ga) == (side < 0)
            lo = np.where(crosses & entering, np.maximum(lo, cross), lo)
            hi = np.where(crosses & ~entering, np.minimum(hi, cross), hi)
        mid = (lo + hi) / 2
        ok = (lo < hi) & (self._box(*uv(mid, phi_a)[1:]) <= 1e-12)
        return np.where(ok, lo, np.nan), np.where(ok, hi, np.nan)


@dataclass(frozen=True)
class SlotCut:
    """An axial slot: radial component ``∈ [floor, top]``; across (tangential ``t``) and along
    ``z`` the rectangle ``|t| ≤ width/2``, ``z ∈ [z0, z1]``, or with ``end_radius`` > 0 the
    rounded slot an end mill of that radius leaves when its centre runs from ``z0`` to ``z1``:
    the rectangle ``|t| ≤ width/2 − end_radius`` dilated by ``end_radius``."""

    id: str
    azimuth: float
    floor_radius: float
    top_radius: float
    width: float
    z0: float
    z1: float
    end_radius: float = 0.0

    def local(self, rho, theta, z):
        d = np.asarray(theta, float) - self.azimuth
        return np.asarray(rho) * np.sin(d), np.asarray(rho) * np.cos(d), np.asarray(z, float)

    def sdf(self, rho, theta, z) -> np.ndarray:
        """Exact signed distance to the slot (mm)."""
        t, r, zz = self.local(rho, theta, z)
        e = self.end_radius
        foot = box_sdf(t, zz - (self.z0 + self.z1) / 2, self.width / 2 - e, (self.z1 - self.z0) / 2) - e
        rad = np.abs(r - (self.floor_radius + self.top_radius) / 2) - (self.top_radius - self.floor_radius) / 2
        return np.hypot(np.maximum(foot, 0), np.maximum(rad, 0)) + np.minimum(np.maximum(foot, rad), 0)

    def half_width(self, z) -> np.ndarray:
        """Half the slot's width at height ``z`` (NaN beyond its ends)."""
        z = np.asarray(z, float)
        e = self.end_radius
        beyond = np.maximum(self.z0 - z, z - self.z1)
        cap = self.width / 2 - e + np.sqrt(np.maximum(e * e - beyond**2, 0.0))
        return np.where(beyond <= 0, self.width / 2, np.where(beyond <= e, cap, np.nan))

    def ray_interval(self, theta, z, rho_max: float) -> tuple[np.ndarray, np.ndarray]:
        """Exact ``(lo, hi)`` of radial rays inside the slot, NaN where they miss."""
        theta, z = np.broadcast_arrays(np.asarray(theta, float), np.asarray(z, float))
        d = theta - self.azimuth
        c, s = np.cos(d), np.abs(np.sin(d))
        hw = self.half_width(z)
        with np.errstate(divide="ignore", invalid="ignore"):
            lo = np.where(c > 0, self.floor_radius / c, np.inf)
            hi = np.minimum(np.where(c > 0, self.top_radius / c, -np.inf), np.where(s > 0, hw / s, np.inf))
        hi = np.minimum(hi, rho_max)
        ok = (lo < hi) & np.isfinite(hw)
        return np.where(ok, lo, np.nan), np.where(ok, hi, np.nan)


def cylinder_ray_interval(theta, z, azimuth, y_offset, z_axis, tip, radius, top=np.inf):
    """``(lo, hi)`` of radial rays inside a flat-bottomed cylinder whose axis is parallel to the
    radial direction at ``azimuth``, offset ``y_offset`` along ``−e_θ`` (machine +Y), at height
    ``z_axis``, its flat end ``tip`` mm from the axis and open up to ``top``; NaN where missed.

    A ray point ``ρ e_r(θ) + z e_z`` is inside when its distance from the cylinder's axis,
    ``√((ρ sin Δ + y)² + (z − z_axis)²)`` with ``Δ = θ − azimuth``, is at most ``radius`` and
    ``tip ≤ ρ cos Δ ≤ top``. All arguments broadcast.
    """
    d = np.asarray(theta, float) - azimuth
    c, s = np.cos(d), np.sin(d)
    h2 = radius * radius - (np.asarray(z, float) - z_axis) ** 2
    half = np.sqrt(np.maximum(h2, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        a = (-half - y_offset) / s
        b = (half - y_offset) / s
        lat_lo = np.where(s != 0, np.minimum(a, b), np.where(np.abs(y_offset) <= half, -np.inf, np.inf))
        lat_hi = np.where(s != 0, np.maximum(a, b), np.where(np.abs(y_offset) <= half, np.inf, -np.inf))
        ax_lo = np.where(c > 0, tip / c, np.inf)
        ax_hi = np.where(c > 0, top / c, -np.inf)
    lo = np.maximum(np.maximum(lat_lo, ax_lo), 0.0)
    hi = np.minimum(lat_hi, ax_hi)
    ok = (h2 >= 0) & (lo < hi)
    return np.where(ok, lo, np.nan), np.where(ok, hi, np.nan)


@dataclass(frozen=True)
class PocketCut:
    """A flat-bottomed radial hole: axis along ``e_r(azimuth)`` at height ``z``, floor
    ``floor_radius`` from the body axis, ``depth`` long."""

    id: str
    azimuth: float
    z: float
    floor_radius: float
    diameter: float
    depth: float

    def sdf(self, rho, theta, z) -> np.ndarray:
        """Exact signed distance to the cylinder (mm)."""
        d = np.asarray(theta, float) - self.azimuth
        lat = np.hypot(np.asarray(rho) * np.sin(d), np.asarray(z, float) - self.z)
        ax = np.asarray(rho) * np.cos(d) - self.floor_radius - self.depth / 2
        return box_sdf(lat, ax, self.diameter / 2, self.depth / 2)

    def ray_interval(self, theta, z, rho_max: float) -> tuple[np.ndarray, np.ndarray]:
        lo, hi = cylinder_ray_interval(
            theta, z, self.azimuth, 0.0, self.z, self.floor_radius, self.diameter / 2, self.floor_radius + self.depth
        )
        return lo, np.minimum(hi, rho_max)


Cut = EllipseCut | SlotCut | PocketCut


@dataclass(frozen=True)
class CutPlan:
    """The stock and every reference cut of one body."""

    name: str
    stock: Stock
    ellipses: tuple[EllipseCut, ...] = ()
    slots: tuple[SlotCut, ...] = ()
    pockets: tuple[PocketCut, ...] = ()

    @property
    def cuts(self) -> tuple[Cut, ...]:
        return (*self.ellipses, *self.slots, *self.pockets)


# ---- tools, cutting data and the machine ------------------------------------------------------

#: stock end-mill diameters (mm) the pocket tool is chosen from
STOCK_END_MILLS = (0.2, 0.25, 0.3, 0.4, 0.5, 0.6, 0.8, 1.0, 1.2, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0)


@dataclass(frozen=True)
class Tool:
    """A flat (square) end mill and its cutting data.

    ``rpm`` = min(spindle top speed, cutting speed / (π D)); ``feed`` (mm/min) =
    rpm × flutes × feed per tooth; ramps, helices and plunges run at ``plunge_feed`` = feed / 2.
    """

    number: int
    diameter: float
    rpm: float
    feed: float
    plunge_feed: float
    shape: Literal["flat"] = "flat"

    @property
    def radius(self) -> float:
        return self.diameter / 2


def make_tool(
    number: int, diameter: float, cutting_speed: float, max_rpm: float, flutes: int, feed_per_tooth_ratio: float
) -> Tool:
    """A :class:`Tool` with its spindle speed and feeds (cutting speed in m/min)."""
    rpm = min(max_rpm, cutting_speed * 1000.0 / (math.pi * diameter))
    feed = rpm * flutes * feed_per_tooth_ratio * diameter
    return Tool(number, diameter, round(rpm), round(feed, 1), round(feed / 2, 1))


@dataclass(frozen=True)
class Tooling:
    """The two end mills and the entry strategy of one program."""

    groove: Tool
    pocket: Tool
    step_down: float
    ramp_angle: float


def pocket_tool_diameter(pocket_diameter: float, chosen: float | None = None) -> float:
    """The pocket end mill: ``chosen``, or the largest stock size in ``[D/2, 0.8 D]``, so that one
    circle at radius ``(D − d)/2`` clears the whole floor (``d ≥ D/2``) with wall to spare."""
    if chosen is not None:
        if not pocket_diameter / 2 <= chosen <= pocket_diameter:
            raise ValueError(
                f"pocket tool {chosen} mm: expected between half the pocket ({pocket_diameter / 2:g} mm) "
                f"and the pocket diameter ({pocket_diameter:g} mm)"
            )
        return chosen
    fits = [d for d in STOCK_END_MILLS if pocket_diameter / 2 <= d <= 0.8 * pocket_diameter]
    if not fits:
        raise ValueError(
            f"no stock end mill between {pocket_diameter / 2:g} and {0.8 * pocket_diameter:g} mm "
            f"for a {pocket_diameter:g} mm pocket; set manufacturing.cnc.pocket_tool_diameter"
        )
    return max(fits)


def tooling(cnc, pocket_diameter: float | None) -> Tooling:
    """Tools and entries from a design's ``manufacturing.cnc`` settings (:class:`CncProfile`)."""
    mk = dict(
        cutting_speed=cnc.cutting_speed,
        max_rpm=cnc.spindle_max_rpm,
        flutes=cnc.flutes,
        feed_per_tooth_ratio=cnc.feed_per_tooth_ratio,
    )
    groove = make_tool(1, cnc.tool_diameter, **mk)
    pd = pocket_tool_diameter(pocket_diameter, cnc.pocket_tool_diameter) if pocket_diameter else cnc.tool_diameter
    pocket = groove if abs(pd - groove.diameter) < 1e-9 else make_tool(2, pd, **mk)
    return Tooling(groove, pocket, cnc.step_down_ratio * cnc.tool_diameter, math.radians(cnc.ramp_angle_deg))


@dataclass(frozen=True)
class Machine:
    """What the cycle time and the safe heights assume about the machine.

    Rapids: ``rapid_linear`` mm/min along X, Y, Z together, ``rapid_a`` deg/min on A (a
    move takes as long as its slowest axis; acceleration is ignored). ``tool_change_s``
    per M6. ``clearance``: the safe height above the stock's outer surface for every
    rotation and traverse; ``approach``: where rapids stop above the surface before a feed.
    """

    rapid_linear: float = 5000.0
    rapid_a: float = 3600.0
    tool_change_s: float = 10.0
    clearance: float = 2.0
    approach: float = 0.5
