"""Compiled pose of a configuration: the platform's rotation (paper eq. 1) and the drones'
positions in the platform frame (eq. 2), as :mod:`flycrane.model.kinematics` computes them.

Both the statics (:func:`flycrane.model.statics_kernel.statics_row`) and the collision check
(:func:`flycrane.world.collision_kernel.collision_free_row`) need them; a state check
(:func:`flycrane.planning.validity_kernel.state_check`) passes the statics' on to its
collision test rather than computing them twice. One formula, one operation order: the
parts' results are bit for bit what each computes alone.
"""

from __future__ import annotations

import math

from flycrane.kernels import kernel


@kernel(inline="always")
def rotation_into(q, rot) -> None:
    """R = Rz(phi) Ry(theta) Rz(sigma - phi) of q (9,) into rot (3, 3), the formula of
    :func:`~flycrane.model.kinematics.matrix_from_tilt_torsion`."""
    phi, theta, sigma = q[3], q[4], q[5]
    cp, sp = math.cos(phi), math.sin(phi)
    ct, st = math.cos(theta), math.sin(theta)
    cs, ss = math.cos(sigma - phi), math.sin(sigma - phi)
    rot[0, 0] = cp * ct * cs - sp * ss
    rot[0, 1] = -cp * ct * ss - sp * cs
    rot[0, 2] = cp * st
    rot[1, 0] = sp * ct * cs + cp * ss
    rot[1, 1] = -sp * ct * ss + cp * cs
    rot[1, 2] = sp * st
    rot[2, 0] = -st * cs
    rot[2, 1] = st * ss
    rot[2, 2] = ct


@kernel(inline="always")
def drone_offset(q, k, foot, radius, outward, up) -> tuple[float, float, float]:
    """Drone k's position a'_k in the platform frame at its alpha q[6 + k]:
    F_k + h_k (cos a n_k + sin a z_k), the formula of
    :func:`~flycrane.model.kinematics.drone_positions_in_platform_frame`."""
    ca, sa = math.cos(q[6 + k]), math.sin(q[6 + k])
    return (
        foot[k, 0] + radius[k] * (ca * outward[k, 0] + sa * up[k, 0]),
        foot[k, 1] + radius[k] * (ca * outward[k, 1] + sa * up[k, 1]),
        foot[k, 2] + radius[k] * (ca * outward[k, 2] + sa * up[k, 2]),
    )


@kernel(inline="always")
def drone_offsets_into(q, foot, radius, outward, up, out) -> None:
    """The three drones' :func:`drone_offset` into out (3, 3), a row per drone."""
    for k in range(3):
        out[k, 0], out[k, 1], out[k, 2] = drone_offset(q, k, foot, radius, outward, up)
