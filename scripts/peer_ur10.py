"""pybotics' least-squares calibration of the UR10 on rigcal recordings (scripts/peer_ur10.sh).

    python3 scripts/peer_ur10.py TRAIN_DIR HELD_DIR... [--every N]

Each DIR is a recording `rigcal import` wrote (measurements.csv: q1_deg..q6_deg, x_mm, y_mm,
z_mm in the laser tracker's frame). The arm is the UR10 of ur10-landgraf/ur10.urdf, written
here in modified D-H for pybotics (mm, rad): the URDF's chain is UR's standard D-H
(d1 127.3, a2 −612, a3 −572.3, d4 163.941, d5 115.7, d6 92.2; α1 = α4 = 90°, α5 = −90°), and
standard D-H Rz(θ)·Tz(d)·Tx(a)·Rx(α) regroups into modified rows (α_{k−1}, a_{k−1}, θ_k, d_k)
because Tx and Rx commute. pybotics' own ur10() is the older CB2 arm (612.7, 571.6, 118 mm),
so it is not used. The tracker frame is pybotics' world frame, started from the closed-form
(Kabsch) registration of the nominal arm; the T-Mac probe is the tool's position.

Fitted, by scipy.optimize.least_squares (trust-region reflective) on pybotics' per-pose
absolute position errors (its own calibration recipe, `optimize_accuracy`): the world frame
(6), the tool position (3), and of the modified D-H rows 2..6 every α, a and θ, plus d of rows
4 and 5 — 25 parameters. Left out because the world frame, the tool or a sum already holds
them: row 1 (world frame), d of rows 2 and 3 (parallel axes 2–4: only the sum of their d acts,
kept in row 4), θ and d of row 6 (the tool's position). pybotics has no Hayati β, so a tilt
between the parallel axes shows as residual (rigcal's rig adds β there).

Held out: each other recording keeps the fitted arm and tool, and only its world frame is
refitted (closed-form rigid registration of the predicted points), as `rigcal evaluate
--refit-frame` does. Printed per recording: 3-D position error mean / RMS / max in mm, and,
when the recording has orientations (roll_deg, pitch_deg, yaw_deg: R = Rz(yaw)·Ry(pitch)·
Rx(roll)), the angle between the measured and the predicted probe frame, mean / RMS / max in
degrees. pybotics fits positions only and its tool has no rotation, so the probe's rotation C
on the flange is the rotation nearest Σ R_predictedᵀ·R_measured over the held-out rows, as
`rigcal evaluate` fits it for every model; the predicted frame is the refitted world frame's
rotation times the flange's.
"""
import csv
import sys
import time

import numpy as np
from scipy.optimize import least_squares

from pybotics.optimization import OptimizationHandler, optimize_accuracy
from pybotics.robot import Robot
from pybotics.tool import Tool


def ur10():
    """The UR10 of ur10.urdf as a pybotics modified-D-H robot (mm, rad), world frame identity."""
    d = [127.3, 0.0, 0.0, 163.941, 115.7, 92.2]
    a = [0.0, -612.0, -572.3, 0.0, 0.0, 0.0]
    alpha = [np.pi / 2, 0.0, 0.0, np.pi / 2, -np.pi / 2, 0.0]
    rows = [[0.0, 0.0, 0.0, d[0]]]
    rows += [[alpha[k - 1], a[k - 1], 0.0, d[k]] for k in range(1, 6)]
    robot = Robot.from_parameters(np.array(rows))
    robot.joint_limits = np.array([[-2 * np.pi] * 6, [2 * np.pi] * 6])
    robot.tool = Tool()
    return robot


def read(directory, every=1):
    """Joint vectors (rad) and measured points (mm) of a recording's `ok` rows."""
    qs, ps, _ = read_poses(directory, every)
    return qs, ps


def rpy_matrix(roll, pitch, yaw):
    """R = Rz(yaw)·Ry(pitch)·Rx(roll), angles in radians (rigcal's files)."""
    cr, sr, cp, sp, cy, sy = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    return rz @ ry @ rx


def read_poses(directory, every=1):
    """Joint vectors (rad), measured points (mm) and measured rotations (3×3, or None when the
    recording has no orientation) of a recording's `ok` rows."""
    qs, ps, rs = [], [], []
    with open(f"{directory}/measurements.csv", newline="") as f:
        for row in csv.DictReader(f):
            if row.get("status", "ok") != "ok":
                continue
            qs.append([float(row[f"q{j}_deg"]) for j in range(1, 7)])
            ps.append([float(row[c]) for c in ("x_mm", "y_mm", "z_mm")])
            if row.get("roll_deg"):
                rs.append(rpy_matrix(*np.deg2rad([float(row[c]) for c in ("roll_deg", "pitch_deg", "yaw_deg")])))
    rotations = np.array(rs)[::every] if len(rs) == len(qs) and rs else None
    return np.deg2rad(np.array(qs))[::every], np.array(ps)[::every], rotations


def nearest_rotation(m):
    """The rotation nearest the 3×3 matrix `m` (Frobenius): U·diag(1, 1, det(U·Vᵀ))·Vᵀ."""
    u, _, vt = np.linalg.svd(m)
    return u @ np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))]) @ vt


def orientation_errors(robot, qs, measured, world_rotation):
    """Angles (deg) between the measured and the predicted probe frames: predicted =
    world_rotation · R_flange(q) · C, C the rotation nearest Σ predictedᵀ·measured."""
    world = robot.world_frame.copy()
    robot.world_frame = np.eye(4)
    flange = np.array([world_rotation @ robot.fk(q)[:3, :3] for q in qs])
    robot.world_frame = world
    c = nearest_rotation(sum(f.T @ r for f, r in zip(flange, measured)))
    cosines = [(np.trace(r.T @ f @ c) - 1.0) / 2.0 for f, r in zip(flange, measured)]
    return np.degrees(np.arccos(np.clip(cosines, -1.0, 1.0)))


def kabsch(model, measured):
    """The rigid transform (4×4) taking `model` points onto `measured` (least squares)."""
    cm, cs = model.mean(0), measured.mean(0)
    h = (model - cm).T @ (measured - cs)
    u, _, vt = np.linalg.svd(h)
    s = np.diag([1.0, 1.0, np.sign(np.linalg.det(vt.T @ u.T))])
    r = vt.T @ s @ u.T
    t = np.eye(4)
    t[:3, :3] = r
    t[:3, 3] = cs - r @ cm
    return t


def start_world_and_tool(robot, qs, positions, rounds=8):
    """Start values for the world frame and the tool position (the probe sits ~100 mm off the
    flange): alternately the closed-form world frame for the current tool, and the tool
    position by linear least squares for that frame (p = W·F(q)·t is linear in t)."""
    flange = [None] * len(qs)
    for _ in range(rounds):
        robot.world_frame = np.eye(4)
        tool = robot.tool.position.copy()
        robot.tool.position = np.zeros(3)
        flange = [robot.fk(q) for q in qs]
        robot.tool.position = tool
        tip = np.array([f[:3, :3] @ tool + f[:3, 3] for f in flange])
        w = kabsch(tip, positions)
        a = np.vstack([w[:3, :3] @ f[:3, :3] for f in flange])
        b = np.concatenate([p - w[:3, :3] @ f[:3, 3] - w[:3, 3] for f, p in zip(flange, positions)])
        robot.tool.position = np.linalg.lstsq(a, b, rcond=None)[0]
        robot.world_frame = w


def predicted(robot, qs):
    return np.array([robot.fk(q)[:3, 3] for q in qs])


def stats(errors):
    n = np.linalg.norm(errors, axis=1)
    return n.mean(), float(np.sqrt(np.mean(n**2))), n.max()


def held_out(robot, qs, positions):
    """Position errors with only the world frame refitted (closed form), and that frame's
    rotation."""
    world = robot.world_frame.copy()
    robot.world_frame = np.eye(4)
    model = predicted(robot, qs)
    robot.world_frame = world
    t = kabsch(model, positions)
    return positions - (model @ t[:3, :3].T + t[:3, 3]), t[:3, :3]


def main():
    args = sys.argv[1:]
    every = 1
    if "--every" in args:
        i = args.index("--every")
        every = int(args[i + 1])
        del args[i : i + 2]
    train, held = args[0], args[1:]
    qs, positions = read(train, every)
    robot = ur10()
    start_world_and_tool(robot, qs, positions)
    before = positions - predicted(robot, qs)
    mask = np.zeros(robot.kinematic_chain.num_parameters, dtype=bool)
    for row in range(1, 6):
        for field in (0, 1, 2):  # α, a, θ
            mask[4 * row + field] = row != 5 or field != 2
    mask[4 * 3 + 3] = mask[4 * 4 + 3] = True  # d of rows 4 and 5
    handler = OptimizationHandler(
        robot=robot,
        kinematic_chain_mask=list(mask),
        tool_mask=[True, True, True, False, False, False],
        world_mask=True,
    )
    x0 = handler.generate_optimization_vector()
    t0 = time.perf_counter()
    result = least_squares(
        fun=optimize_accuracy, x0=x0, args=(handler, qs, positions), x_scale="jac", max_nfev=60
    )
    fit_s = time.perf_counter() - t0
    handler.apply_optimization_vector(result.x)
    robot = handler.robot
    after = positions - predicted(robot, qs)
    print(
        f"pybotics on {train} ({len(qs)} poses): {len(x0)} parameters, {result.nfev} evaluations "
        f"({result.message.rstrip('.')}), "
        f"training RMS {stats(before)[1]:.3f} -> {stats(after)[1]:.4f} mm (3-D), "
        f"fit {fit_s:.3f} s (the least-squares call)"
    )
    print(f"tool position {robot.tool.position.round(3)} mm")
    for directory in held:
        q, p, rotations = read_poses(directory)
        errors, world_rotation = held_out(robot, q, p)
        m, r, x = stats(errors)
        line = f"held out {directory} ({len(q)} poses, world frame refitted): mean {m:.3f} / RMS {r:.3f} / max {x:.3f} mm"
        if rotations is not None:
            a = orientation_errors(robot, q, rotations, world_rotation)
            line += f"; orientation mean {a.mean():.3f} / RMS {np.sqrt(np.mean(a**2)):.3f} / max {a.max():.3f} deg"
        print(line)


if __name__ == "__main__":
    main()
