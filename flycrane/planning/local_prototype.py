import math, numba, numpy as np
from flycrane.planning.interpolation import quaternion_from_angles, angles_from_quaternion, wrap

@numba.njit(cache=True, nogil=True)
def perturb_into(q, noise, bounds, out):
    """q moved by noise (9,): position offsets, a rotation vector (world axes), alpha offsets;
    clipped into the bounds."""
    for a in range(3):
        out[a] = min(bounds[3 + a], max(bounds[a], q[a] + noise[a]))
    qa = np.empty(4)
    quaternion_from_angles(q[3], q[4], q[5], qa)
    angle = math.sqrt(noise[3] ** 2 + noise[4] ** 2 + noise[5] ** 2)
    dq = np.empty(4)
    if angle < 1e-12:
        dq[0], dq[1], dq[2], dq[3] = 1.0, 0.0, 0.0, 0.0
    else:
        s = math.sin(0.5 * angle) / angle
        dq[0], dq[1], dq[2], dq[3] = math.cos(0.5 * angle), s * noise[3], s * noise[4], s * noise[5]
    w = dq[0] * qa[0] - dq[1] * qa[1] - dq[2] * qa[2] - dq[3] * qa[3]
    x = dq[0] * qa[1] + dq[1] * qa[0] + dq[2] * qa[3] - dq[3] * qa[2]
    y = dq[0] * qa[2] - dq[1] * qa[3] + dq[2] * qa[0] + dq[3] * qa[1]
    z = dq[0] * qa[3] + dq[1] * qa[2] - dq[2] * qa[1] + dq[3] * qa[0]
    qa[0], qa[1], qa[2], qa[3] = w, x, y, z
    angles_from_quaternion(qa, out, 3)
    if out[4] > bounds[6]:
        out[4] = bounds[6]
    for k in range(6, 9):
        out[k] = min(bounds[8], max(bounds[7], q[k] + noise[k]))
