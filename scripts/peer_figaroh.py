"""FIGAROH's geometric calibration of a serial arm on a rigcal recording (scripts/peers.sh).

Install (peers only: never a build or test dependency of rigcal). From PyPI, Python 3.11+ (the script reads TOML with tomllib):
    pip install figaroh
It pulls pinocchio as the `pin` wheel (with its cmeel-* libraries), ndcurves, picos, meshcat,
rospkg, pandas and matplotlib: no compiler, no network at run time. Tested with figaroh 1.0.2,
pin 4.1.0, numpy 2.4, scipy 1.17 (Python 3.11). If `import figaroh` fails on pinocchio, install
its wheel first (`pip install pin`) and figaroh again. figaroh 1.0 reads only its "unified" YAML
configuration (a legacy flat one is refused); this script writes one per run.

    python3 scripts/peer_figaroh.py RECORDING_DIR --rig RIG.toml
    python3 scripts/peer_figaroh.py RECORDING_DIR --urdf ROBOT.urdf --base LINK --tip LINK

RECORDING_DIR holds a rigcal recording's measurements.csv (q1_deg.., x_mm, y_mm, z_mm; `ok`
rows are used). With --rig the arm's URDF is written from the rig file (rigcal has no URDF of a
rig that did not come from one: `rigcal export urdf` folds a model into the URDF a rig was made
from), in the rig's five-parameter convention A_k = Rz(θ_k + q_k)·Tz(d_k)·Tx(a_k)·Rx(α_k)·Ry(β_k)
between the base transform and the tool: joint k's URDF origin is the fixed part of A_{k−1}
(Rz(θ)·Tz(d) commutes with Rz(q)), the base transform is joint 1's origin, and the tool a fixed
joint to the link `tip`. With --urdf the recording's joints are the URDF's movable joints from
--base to --tip, in chain order (as `rigcal rig from-urdf` orders them).

What FIGAROH does here is its own calibration recipe (BaseCalibration, the UR10 and TIAGo
examples): `calibration_level: full_params` (six placement errors per moving joint), its
structural parameter selection (QR of the kinematic regressor at random configurations, then
the parameters the frames absorb on the measured configurations dropped), the measurement
(base) frame and the marker position estimated freely (`known_baseframe`/`known_tipframe`
False), started from its closed-form frame guess, and scipy's Levenberg-Marquardt on the
position residuals p_estimated − p_measured in the measurement frame (metres), with its outlier
rounds (2 cm). Every joint of the chain is listed as active, held ones too (the RV-M2's wrist
stays at 0° in its recordings, as rigcal's `held_joints` keep it): FIGAROH's structural
regressor takes every joint's placement, and its data-level step drops the parameters the
held joints leave unidentifiable (listing only the moving joints fails in figaroh 1.0.2: its
regressor still names the held joints' parameters, which its forward kinematics then refuses).

Printed (mm, seconds): the parameter count, the 3-D position RMS at FIGAROH's start (nominal
arm, closed-form frames) and after the fit, the time of the identification set-up
(`initialize()`: data, structural selection) and of the fit (`solve()`), and the process time
up to the end of the fit from the interpreter's start (imports included). The shell runner
times the whole process.
"""
import argparse
import csv
import logging
import os
import sys
import tempfile
import time
import tomllib
import warnings

T_START = time.perf_counter()

import numpy as np  # noqa: E402

OUTLIER_THRESHOLD_M = 0.02


def rot_x(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def five_parameter(p):
    """Rz(θ)·Tz(d)·Tx(a)·Rx(α)·Ry(β) of a rig-file table (mm, degrees) as a 4×4 in metres."""
    theta, alpha, beta = (np.deg2rad(p.get(k, 0.0)) for k in ("theta_deg", "alpha_deg", "beta_deg"))
    d, a = p.get("d_mm", 0.0) / 1000.0, p.get("a_mm", 0.0) / 1000.0
    t = np.eye(4)
    t[:3, :3] = rot_z(theta) @ rot_x(alpha) @ rot_y(beta)
    t[:3, 3] = rot_z(theta) @ np.array([a, 0.0, d])
    return t


def urdf_origin(t):
    """URDF <origin> of a 4×4: xyz (m) and rpy with R = Rz(yaw)·Ry(pitch)·Rx(roll)."""
    r = t[:3, :3]
    pitch = np.arctan2(-r[2, 0], np.hypot(r[0, 0], r[1, 0]))
    if np.hypot(r[0, 0], r[1, 0]) < 1e-12:  # gimbal lock: put the whole yaw into roll
        roll, yaw = np.arctan2(-r[1, 2], r[1, 1]), 0.0
    else:
        roll, yaw = np.arctan2(r[2, 1], r[2, 2]), np.arctan2(r[1, 0], r[0, 0])
    xyz = " ".join(f"{v:.12g}" for v in t[:3, 3])
    rpy = " ".join(f"{v:.17g}" for v in (roll, pitch, yaw))
    # Check the conversion against the matrix it came from (a wrong URDF would bias the fit).
    assert np.allclose(rot_z(yaw) @ rot_y(pitch) @ rot_x(roll), r, atol=1e-12), "rpy round trip"
    return f'<origin xyz="{xyz}" rpy="{rpy}"/>'


def urdf_from_rig(rig_path):
    """The URDF of a rig file's arm (module docstring), its base and tip link, its joint names."""
    with open(rig_path, "rb") as f:
        robot = tomllib.load(f)["robot"]
    joints = robot["joints"]
    for j in joints:
        if j.get("type", "revolute") != "revolute":
            sys.exit(f"{rig_path}: joint {j['name']} is {j['type']}; this script writes revolute joints only")
    links = ["rig_world"] + [f"link_{j['name']}" for j in joints] + ["tip"]
    lines = [f'<robot name="{robot.get("name", "arm").replace(" ", "_")}">']
    lines += [f'  <link name="{name}"/>' for name in links]
    origin = five_parameter(robot.get("base", {}))
    for k, j in enumerate(joints):
        lo, hi = np.deg2rad(j.get("limits_deg", [-180.0, 180.0]))
        lines += [
            f'  <joint name="{j["name"]}" type="revolute">',
            f'    <parent link="{links[k]}"/>',
            f'    <child link="{links[k + 1]}"/>',
            f"    {urdf_origin(origin)}",
            '    <axis xyz="0 0 1"/>',
            f'    <limit lower="{lo:.12g}" upper="{hi:.12g}" effort="100" velocity="1"/>',
            "  </joint>",
        ]
        origin = five_parameter(j)
    tool = origin @ five_parameter(robot.get("tool", {}))
    lines += [
        '  <joint name="tool" type="fixed">',
        f'    <parent link="{links[-2]}"/>',
        '    <child link="tip"/>',
        f"    {urdf_origin(tool)}",
        "  </joint>",
        "</robot>",
    ]
    return "\n".join(lines) + "\n", "universe", "tip", [j["name"] for j in joints]


def read_recording(directory, n_joints):
    """Joint angles (rad, rig order) and measured points (mm) of the recording's `ok` rows."""
    qs, ps = [], []
    with open(os.path.join(directory, "measurements.csv"), newline="") as f:
        for row in csv.DictReader(f):
            if row.get("status", "ok") != "ok" or not row.get("x_mm"):
                continue
            qs.append([float(row[f"q{j}_deg"]) for j in range(1, n_joints + 1)])
            ps.append([float(row[c]) for c in ("x_mm", "y_mm", "z_mm")])
    if not qs:
        sys.exit(f"{directory}/measurements.csv has no `ok` rows with a measured point")
    return np.deg2rad(np.array(qs)), np.array(ps)


def write_inputs(work, joints, qs, points_mm, base, tip):
    """FIGAROH's data CSV (x1, y1, z1 in metres, one column per joint in rad) and its unified
    configuration (position-only marker, full_params, frames unknown)."""
    data = os.path.join(work, "figaroh_data.csv")
    with open(data, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["x1", "y1", "z1"] + joints)
        for q, p in zip(qs, points_mm / 1000.0):
            w.writerow([repr(float(v)) for v in p] + [repr(float(v)) for v in q])
    config = os.path.join(work, "figaroh_config.yaml")
    quoted = ", ".join(f'"{n}"' for n in joints)
    with open(config, "w") as f:
        f.write(
            f"""robot:
  name: "peer"
  properties:
    joints:
      active_joints: [{quoted}]
tasks:
  calibration:
    enabled: true
    parameters:
      calibration_level: "full_params"
      include_non_geometric: false
      outlier_threshold: {OUTLIER_THRESHOLD_M}
    kinematics:
      base_frame: "{base}"
      tool_frame: "{tip}"
    measurements:
      markers:
        - name: "probe"
          reference_joint: "{joints[-1]}"
          measurable_dof: [true, true, true, false, false, false]
      poses:
        base_pose: [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
        tool_pose: [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    data:
      source_file: "{data}"
      validation_data_file: ""
      number_of_samples: {len(qs)}
"""
        )
    return config


def rms_mm(residual_m, n):
    """3-D position RMS (mm) of a flat FIGAROH position residual (component-major, metres)."""
    e = np.asarray(residual_m)[: 3 * n].reshape(3, n)
    return float(np.sqrt(np.mean(np.sum(e**2, axis=0)))) * 1000.0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("recording")
    ap.add_argument("--rig", help="rig file (TOML) to write the URDF from")
    ap.add_argument("--urdf", help="the arm's URDF (with --base and --tip)")
    ap.add_argument("--base", help="URDF link the chain starts at")
    ap.add_argument("--tip", help="URDF link the measured point is fixed to")
    args = ap.parse_args()
    if bool(args.rig) == bool(args.urdf) or (args.urdf and not (args.base and args.tip)):
        ap.error("give either --rig RIG.toml, or --urdf ROBOT.urdf with --base LINK and --tip LINK")

    warnings.filterwarnings("ignore")  # pinocchio/ndcurves converter notices at import
    logging.disable(logging.WARNING)
    from figaroh.calibration.base_calibration import BaseCalibration
    from figaroh.calibration.calibration_tools import calc_updated_fkm
    from figaroh.calibration.config import get_sup_joints
    from figaroh.tools.robot import load_robot

    class PositionCalibration(BaseCalibration):
        """Position residuals in the measurement frame, as the peers and rigcal fit them."""

        def cost_function(self, var):
            estimated = calc_updated_fkm(self.model, self.data, var, self.q_measured, self.calib_config)
            return self._compute_logmap_residuals(self.PEE_measured, estimated, position_frame="world")

    with tempfile.TemporaryDirectory() as work:
        if args.rig:
            text, base, tip, joint_names = urdf_from_rig(args.rig)
            urdf = os.path.join(work, "arm.urdf")
            with open(urdf, "w") as f:
                f.write(text)
        else:
            urdf, base, tip = args.urdf, args.base, args.tip
        robot = load_robot(urdf, package_dirs=work, load_by_urdf=True)
        if not args.rig:
            for link in (base, tip):
                if not robot.model.existFrame(link):
                    sys.exit(f"{urdf} has no link {link}: give --base and --tip as the URDF names them")
            joint_names = [robot.model.names[i] for i in get_sup_joints(robot.model, base, tip)]
        qs, points = read_recording(args.recording, len(joint_names))
        config = write_inputs(work, joint_names, qs, points, base, tip)

        calib = PositionCalibration(robot, config)
        calib.calib_config["known_baseframe"] = False
        calib.calib_config["known_tipframe"] = False

        t0 = time.perf_counter()
        calib.initialize()
        t1 = time.perf_counter()
        n = calib.calib_config["NbSample"]
        names = calib.calib_config["param_name"]
        guess = calib.initial_frame_guess()
        start = np.array([guess.get(p, 0.0) for p in names])
        before = rms_mm(calib.cost_function(start), n)
        t2 = time.perf_counter()
        result = calib.solve(enable_logging=False)
        t3 = time.perf_counter()
        after = rms_mm(calib.cost_function(result.x), n)
        excluded = len(getattr(calib, "outlier_indices", []) or [])

    print(
        f"figaroh on {args.recording} ({n} poses, joints {','.join(joint_names)}): {len(names)} parameters "
        f"({result.nfev} evaluations, {excluded} outliers), RMS {before:.3f} -> {after:.4f} mm; "
        f"set-up {t1 - t0:.3f} s, fit {t3 - t2:.3f} s (the process up to its end: {t3 - T_START:.3f} s)"
    )


if __name__ == "__main__":
    main()
