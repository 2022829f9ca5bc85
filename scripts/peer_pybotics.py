"""pybotics' least-squares calibration of the RV-M2 on a rigcal recording (scripts/peer-pybotics.sh).

The rig's chain (rigs/rv-m2-ideal.toml, five-parameter convention
A = Rz(θ)·Tz(d)·Tx(a)·Rx(α)·Ry(β) with β = 0) is the same chain in modified D-H: link k carries
joint k's θ, d and joint k−1's a, α (Tx and Rx commute); the base transform is pybotics' world
frame and J5's a, α plus the 170 mm pin along x its tool. Fifteen parameters are fitted, as
rigcal fits fifteen: the world frame (6), θ, a, α of links 2 and 4 and θ, a of link 3 (8), the
tool's x (1), by scipy.optimize.least_squares (trust-region reflective, its default) on
pybotics' per-pose absolute position errors, which is pybotics' own calibration recipe.
Prints the RMS position residual before and after (mm) and the fit's time (the least-squares
call alone, seconds; the shell runners time the whole process).
"""
import csv
import sys
import time

import numpy as np
from scipy.optimize import least_squares

from pybotics.geometry import vector_2_matrix
from pybotics.optimization import OptimizationHandler, compute_absolute_errors, optimize_accuracy
from pybotics.robot import Robot
from pybotics.tool import Tool


def dh_matrix(theta, d, a, alpha):
    """Rz(θ)·Tz(d)·Tx(a)·Rx(α)."""
    ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
    return np.array(
        [
            [ct, -st * ca, st * sa, a * ct],
            [st, ct * ca, -ct * sa, a * st],
            [0.0, sa, ca, d],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def rv_m2():
    """The RV-M2 of rigs/rv-m2-ideal.toml as a pybotics MDH robot (mm, rad)."""
    deg = np.deg2rad
    # Joints' (a, α) in the rig file; θ = d = 0 for every joint.
    a = [120.0, 250.0, 265.0, 0.0, 0.0]
    alpha = [deg(-90.0), 0.0, deg(-90.0), deg(90.0), 0.0]
    # MDH rows: α_{k-1}, a_{k-1}, θ_k, d_k.
    mdh = [[0.0, 0.0, 0.0, 0.0]] + [[alpha[k - 1], a[k - 1], 0.0, 0.0] for k in range(1, 5)]
    robot = Robot.from_parameters(np.array(mdh))
    robot.world_frame = dh_matrix(deg(90.0), 400.0, -80.0, deg(180.0))
    tool = Tool()
    tool.matrix = dh_matrix(0.0, 0.0, a[4], alpha[4]) @ dh_matrix(0.0, 0.0, 170.0, 0.0)
    robot.tool = tool
    robot.joint_limits = np.array([[-np.pi] * 5, [np.pi] * 5]) * 2
    return robot


def read(path):
    qs, ps = [], []
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            if row.get("status", "ok") != "ok" or not row.get("x_mm"):
                continue
            qs.append([float(row[f"q{j}_deg"]) for j in range(1, 6)])
            ps.append([float(row[c]) for c in ("x_mm", "y_mm", "z_mm")])
    return np.deg2rad(np.array(qs)), np.array(ps)


def main():
    qs, positions = read(sys.argv[1])
    robot = rv_m2()
    # MDH vector per link: α, a, θ, d.
    kc_mask = np.zeros(robot.kinematic_chain.num_parameters, dtype=bool)
    for link, fields in ((1, (0, 1, 2)), (2, (1, 2)), (3, (0, 1, 2))):
        for f in fields:
            kc_mask[4 * link + f] = True
    tool_mask = [True, False, False, False, False, False]
    handler = OptimizationHandler(
        robot=robot, kinematic_chain_mask=list(kc_mask), tool_mask=tool_mask, world_mask=True
    )
    x0 = handler.generate_optimization_vector()
    before = compute_absolute_errors(qs=qs, positions=positions, robot=robot)
    t0 = time.perf_counter()
    result = least_squares(fun=optimize_accuracy, x0=x0, args=(handler, qs, positions))
    fit_s = time.perf_counter() - t0
    handler.apply_optimization_vector(result.x)
    after = compute_absolute_errors(qs=qs, positions=positions, robot=handler.robot)
    rms = lambda e: float(np.sqrt(np.mean(e**2)))
    print(
        f"{len(x0)} parameters, {result.nfev} evaluations, RMS {rms(before):.3f} -> {rms(after):.4f} mm, "
        f"fit {fit_s:.3f} s"
    )


if __name__ == "__main__":
    main()
