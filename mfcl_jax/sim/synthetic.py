"""Synthetic floor plans and candidate sets: the decision layer exercised without the
front-end, by the tests and the speed scripts alike (rows of identical rooms, walks through
them, windows whose candidates a function gives, the scans' evidence drawn from the plan).

``GRID`` and ``N_ROOMS`` are the one grid and room capacity every synthetic building is
padded to, so that one compiled program serves them all; ``row_walk`` is the four-room row
walked to and fro in its first two rooms (no congruence probe)."""

import numpy as np
from shapely.geometry import box

from mfcl_jax.floorplan import Door, Floorplan, Room

PITCH = 7.3
HEIGHT = 5.0
WT = 0.15  # wall thickness


def row_of_rooms(widths=(PITCH,) * 4, height=HEIGHT, door=(2.0, 3.0), name="row", closed=()):
    """Rooms side by side along x, internal doors at ``door`` (y-range), no exterior door.

    Internal walls listed in ``closed`` (1-based wall index i between rooms i-1 and i) have no
    door.
    """
    xs = np.concatenate([[0.0], np.cumsum(widths)])
    walls = [
        [[0, 0], [xs[-1], 0]],
        [[xs[-1], 0], [xs[-1], height]],
        [[xs[-1], height], [0, height]],
        [[0, height], [0, 0]],
    ]
    rooms, doors = [], []
    h = WT / 2
    for i in range(len(widths)):
        rooms.append(Room(f"r{i}", box(xs[i] + h, h, xs[i + 1] - h, height - h)))
    for i in range(1, len(widths)):
        if i in closed:
            walls.append([[xs[i], 0], [xs[i], height]])
            continue
        walls += [[[xs[i], 0], [xs[i], door[0]]], [[xs[i], door[1]], [xs[i], height]]]
        doors.append(Door(np.array([[xs[i], door[0]], [xs[i], door[1]]]), (f"r{i - 1}", f"r{i}")))
    return Floorplan(
        walls=np.array(walls, float),
        thickness=WT,
        rooms=tuple(rooms),
        doors=tuple(doors),
        name=name,
    )


def three_rooms():
    """Three non-congruent rooms (areas differ), like the real 207-209 study."""
    return row_of_rooms(widths=(6.0, 8.5, 4.0), height=6.0, door=(2.5, 3.5), name="three")


def walk(points, step=0.25):
    """Odometry-like samples (T, 3) along a polyline, yaw along the motion."""
    pts = np.asarray(points, float)
    out = []
    for a, b in zip(pts[:-1], pts[1:], strict=True):
        n = max(int(np.ceil(np.linalg.norm(b - a) / step)), 1)
        yaw = np.arctan2(*(b - a)[::-1])
        for s in np.arange(n) / n:
            p = a + s * (b - a)
            out.append([p[0], p[1], yaw])
    out.append([*pts[-1], out[-1][2]])
    return np.asarray(out, float)


def to_odom(traj_b, anchor):
    """Trajectory in B -> odometry frame L given the hidden anchor ^B T_L (on the host: the
    jnp twin compiled each operation anew for every trajectory length)."""
    from mfcl_jax import se2

    return se2.compose_host(se2.inverse_host(anchor), traj_b)


def evidence_at(fp, poses):
    """What a clean 360-beam LiDAR sees of ``fp``'s walls at ``poses (K, 3)``: the evidence
    samples ``(points, origins, mask)`` ``(K, P, ...)`` in each pose's frame."""
    from mfcl_jax.sim import LidarParams, cast, scan_points
    from mfcl_jax.windows.arrays import evidence_sample

    lidar = LidarParams(n_beams=360, sigma=0.0, dropout=0.0)
    pts = np.asarray(scan_points(cast(np.asarray(poses), fp.wall_faces, lidar)), np.float64)
    out = []
    for p in pts:
        p = p[np.all(np.isfinite(p), 1)]
        out.append(evidence_sample(p, np.zeros_like(p)))
    return tuple(np.stack(x) for x in zip(*out, strict=True))


def make_run(traj_b, anchor, n_windows, cand_fn, J=8, fp=None):
    """Candidates for windows evenly spread along ``traj_b`` (B frame).

    ``cand_fn(k, Y_true) -> list of (pose_B (3,), score)`` gives the candidates of window k;
    with ``fp`` each window's evidence is a ray cast of its walls at the true pose (else none).
    Returns a dict of host arrays for one run (K, J padded).
    """
    from mfcl_jax import se2
    from mfcl_jax.windows.arrays import EVIDENCE_POINTS

    traj_l = to_odom(traj_b, anchor)
    t = len(traj_l)
    ends = np.linspace(t // n_windows, t - 1, n_windows).astype(np.int32)
    X = traj_l[ends]
    Y_true = np.asarray(se2.compose(np.asarray(anchor), X))
    H = np.zeros((n_windows, J, 3))
    S = np.zeros((n_windows, J))
    M = np.zeros((n_windows, J), bool)
    for k in range(n_windows):
        cs = cand_fn(k, Y_true[k])
        for j, (pose, sc) in enumerate(cs[:J]):
            H[k, j] = np.asarray(se2.anchor(np.asarray(pose, float), X[k]))
            S[k, j] = sc
            M[k, j] = True
    if fp is not None:
        ev_p, ev_o, ev_m = evidence_at(fp, Y_true)
    else:
        ev_p = np.zeros((n_windows, EVIDENCE_POINTS, 2), np.float32)
        ev_o, ev_m = ev_p.copy(), np.zeros((n_windows, EVIDENCE_POINTS), bool)
    return dict(
        ev_points=ev_p,
        ev_origins=ev_o,
        ev_mask=ev_m,
        H=H.astype(np.float32),
        score=S.astype(np.float32),
        mask=M,
        traj=traj_l.astype(np.float32),
        traj_mask=np.ones(t, bool),
        window_start=np.concatenate([[0], ends[:-1] + 1]).astype(np.int32),  # disjoint windows
        window_end=ends,
        window_mask=np.ones(n_windows, bool),
        X=X,
        Y_true=Y_true,
    )


def shift(pose, dx, dy=0.0):
    return np.asarray(pose, float) + np.array([dx, dy, 0.0])


GRID, N_ROOMS = (340, 340), 6  # the grid and room capacity of every synthetic building
HIDDEN_ANCHOR = np.array([1.0, -2.0, 0.4])  # the hidden ^B T_L of row_walk
ROW_K, ROW_J = 8, 16  # row_walk's windows and candidate capacity


def truth_only(k, y):
    """A window's candidates: the true pose alone, score 1."""
    return [(y, 1.0)]


def row_walk():
    """Four identical rooms in a row (no congruence probe), walked to and fro along y = 2.5
    in the first two: ``(maps, run)``, the maps padded to ``GRID`` and ``N_ROOMS`` (one
    compiled step serves every synthetic building)."""
    import jax
    import jax.numpy as jnp

    from mfcl_jax.decision import decision_maps
    from mfcl_jax.decision.maps import pad_maps

    fp = row_of_rooms()
    m = pad_maps(decision_maps(fp, min_iou=1.01), GRID, N_ROOMS, n_motions=8, n_offsets=32)
    maps = jax.tree.map(jnp.asarray, m)
    path = walk([[10, 2.5], [18, 2.5], [10, 2.5], [18, 2.5]])
    run = make_run(path, HIDDEN_ANCHOR, ROW_K, truth_only, J=ROW_J, fp=fp)
    return maps, run
