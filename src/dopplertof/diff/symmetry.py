"""Axes about which a body's surface maps onto itself: spins a D-ToF capture cannot see.

A capture measures how each path's length changes. A body turning about an axis of
rotational symmetry through its pivot (a torus about its axis, a sphere about any)
occupies the same surface at every instant, so no path length changes: the spin's
component along that axis leaves no trace beyond the facets of a mesh sliding past the
pixels. A fit that frees the angular velocity (``fit --angular``) then reports a value
and an uncertainty for that component that come from the facets only, with nothing of
the true spin in them (the torus of examples/user_meshes.xml, turning at 30 rad/s about
its axis, was fitted to 0.0 +- 0.02 rad/s).

The test: two independent area-uniform samplings A and B of the body's surface at its
pose at mid-exposure; for each principal axis of the surface's second moments about the
pivot (exact over a mesh's triangles, else A's), A
turned about that axis through the pivot by two angles (not fractions of a turn a mesh of
a few dozen segments repeats at) should lie on the surface as closely as A itself does:
the median and 95th percentile of the distances from the turned points to their nearest
point of B within :data:`TOLERANCE` times those of A unturned.
"""

from __future__ import annotations

import numpy as np

#: how much farther from the surface the turned samples may lie than the unturned ones
TOLERANCE = 1.5
#: the turns tried (degrees)
ANGLES_DEG = (23.0, 71.0)


def surface_samples(body, matrix, count: int, seed: int) -> np.ndarray:
    """(count, 3) area-uniform points on ``body``'s shapes (its reference pose) moved by
    the 4x4 ``matrix``."""
    import mitsuba as mi

    shapes = list(body.scene.shapes())
    areas = np.array([float(np.ravel(s.surface_area())[0]) for s in shapes])
    rng = np.random.default_rng(seed)
    counts = rng.multinomial(count, areas / areas.sum())
    points = []
    for shape, n in zip(shapes, counts):
        if n:
            u = rng.random((2, n)).astype(np.float32)
            p = shape.sample_position(0.0, mi.Point2f(u[0], u[1])).p
            points.append(np.stack([np.asarray(p[i], np.float64) for i in range(3)], -1))
    points = np.concatenate(points)
    return points @ matrix[:3, :3].T + matrix[:3, 3]


def surface_moments(body, matrix, pivot):
    """The second moments about ``pivot`` of ``body``'s surface, exact over its triangles
    (each contributes A / 12 (sum v v^T + (sum v)(sum v)^T) of its corners v about the
    pivot), at the pose ``matrix``; None when a shape of it is not a triangle mesh."""
    import mitsuba as mi

    total = np.zeros((3, 3))
    for shape in body.scene.shapes():
        values = mi.traverse(shape)
        if "vertex_positions" not in values or "faces" not in values:
            return None
        v = np.asarray(values["vertex_positions"], np.float64).reshape(-1, 3)
        v = v @ matrix[:3, :3].T + matrix[:3, 3] - pivot
        corners = v[np.asarray(values["faces"], np.int64).reshape(-1, 3)]  # (F, 3, 3)
        area = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0],
                                             corners[:, 2] - corners[:, 0]), axis=-1)
        summed = corners.sum(axis=1)
        total += np.einsum("f,fki,fkj->ij", area / 12, corners, corners)
        total += np.einsum("f,fi,fj->ij", area / 12, summed, summed)
    return total


def turned(points, pivot, axis, angle_deg: float) -> np.ndarray:
    """``points`` turned by ``angle_deg`` about ``axis`` through ``pivot`` (Rodrigues)."""
    k = np.asarray(axis, np.float64) / np.linalg.norm(axis)
    a = np.radians(angle_deg)
    x = np.asarray(points) - pivot
    x = (x * np.cos(a) + np.cross(k, x) * np.sin(a)
         + np.outer(x @ k, k) * (1.0 - np.cos(a)))
    return x + pivot


def symmetry_axes(body, matrix, pivot, count: int = 4000, seed: int = 0) -> list:
    """Unit axes (world) through ``pivot`` about which ``body`` at the pose ``matrix``
    (4x4, applied to its reference pose) is rotationally symmetric (module docstring)."""
    from scipy.spatial import cKDTree

    pivot = np.asarray(pivot, np.float64)
    a = surface_samples(body, matrix, count, seed)
    tree = cKDTree(surface_samples(body, matrix, count, seed + 1))
    base = np.percentile(tree.query(a)[0], [50, 95])
    moments = surface_moments(body, matrix, pivot)
    if moments is None:  # (a shape that is no mesh: the samples' moments)
        moments = np.einsum("ni,nj->ij", a - pivot, a - pivot) / len(a)
    axes = []
    for axis in np.linalg.eigh(moments)[1].T:
        distances = [np.percentile(tree.query(turned(a, pivot, axis, angle))[0], [50, 95])
                     for angle in ANGLES_DEG]
        if all(np.all(d <= TOLERANCE * base) for d in distances):
            axes.append(axis / np.linalg.norm(axis))
    return axes


def symmetry_notes(scene, motions, t_mid: float, bodies: list, angular: bool) -> list:
    """Per fitted body, its :func:`symmetry_axes` at mid-exposure into its fit.json entry
    (``symmetry_axes``); with ``angular``, the spin along them is no measurement: the
    entry's ``angular_velocity_along_symmetry_axes_rad_s`` gives it, its per-component
    errors against the truth (``angular_velocity_error_sigmas``) leave it out, and a
    warning per such body is returned (the fit's warnings)."""
    warnings = []
    for body, motion, entry in zip(scene.bodies, motions, bodies):
        axes = symmetry_axes(body, body.motion.relative_matrix(t_mid), motion.pivot)
        entry["symmetry_axes"] = [[round(float(x), 6) for x in a] for a in axes]
        if not (angular and axes):
            continue
        omega = np.asarray(entry["angular_velocity_rad_s"], np.float64)
        along = [float(omega @ a) for a in axes]
        entry["angular_velocity_along_symmetry_axes_rad_s"] = along
        if "angular_velocity_error_rad_s" in entry:
            _errors_across(entry, axes)
        warnings.append(
            f"body {entry['name']}: its surface maps onto itself when turned about "
            f"{_axis_text(axes)} through its pivot, so a spin about that axis changes no "
            f"path and the captures cannot see it: the fitted spin along it "
            f"({', '.join(f'{w:+.3f}' for w in along)} rad/s) is no measurement, and its "
            "uncertainty is the mesh's facets'")
    return warnings


def _errors_across(entry: dict, axes) -> None:
    """The angular error's components in reported standard deviations, the spin along
    ``axes`` (unseen) left out of the error."""
    error = np.asarray(entry["angular_velocity_error_rad_s"], np.float64)
    across = error - sum((error @ a) * a for a in axes)
    sigma = entry.get("angular_velocity_uncertainty_rad_s") or [None] * 3
    entry["angular_velocity_error_sigmas"] = [
        None if s is None or s == 0 else float(e / s) for e, s in zip(across, sigma)]
    entry["angular_velocity_error_sigmas_leave_out"] = "the spin along symmetry_axes"


def _axis_text(axes) -> str:
    if len(axes) >= 3:
        return "any axis"
    return " and ".join("(" + ", ".join(f"{x:+.2f}" for x in a) + ")" for a in axes)
