#!/usr/bin/env python3
"""Independent check of a generated MMIC-I URDF with Pinocchio (issue 24).

Usage: check_urdf.py CASES.json  -> JSON report on stdout.

CASES.json (written by mib/export/tests/urdf_pinocchio.rs from the MIB):
  {"urdf": path, "root_link": "gripper_a", "pitch": 0.3048,
   "tol_m": 0.0005, "tol_deg": 0.5,
   "cases": [{"name": ..., "joints": {"hip_joint": rad, ...},
              "root": {"face": "Xneg", "approach": "inward"},
              "expect": {"gripper_b": {"face": "Yneg", "approach": "inward"}, ...}}]}

The script only takes the lattice pitch, the joint values, where the root gripper is
clamped and which faces the MIB expects. It loads the URDF with Pinocchio, places the
root link's frame on its face (origin at the face centre on the mid-plane, z along the
face normal as `approach` says, y along world +Z), runs forward kinematics and decides on
its own which face of the voxel each frame lies on: within tol_m of a face plane, inside
the face square, z axis within tol_deg of the face normal. It also checks every link's
mass and inertia (positive mass, positive definite, triangle inequality) from the URDF
text and from Pinocchio's model, reports the model's total mass, and, for the frames a
case lists in "gravity_frames", the gravity vector (world -Y, 1000 mg) in that frame.
"""
import json
import math
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin

FACES = {  # name -> (axis index, sign of the face's position on that axis)
    "Xpos": (0, 1.0), "Xneg": (0, -1.0),
    "Ypos": (1, 1.0), "Yneg": (1, -1.0),
    "Zpos": (2, 1.0), "Zneg": (2, -1.0),
}


def unit(i):
    e = np.zeros(3)
    e[i] = 1.0
    return e


def inward_normal(face):
    axis, sign = FACES[face]
    return -sign * unit(axis)


def face_centre(face, pitch):
    axis, sign = FACES[face]
    return sign * pitch / 2.0 * unit(axis)


def root_placement(face, approach, pitch):
    z = inward_normal(face) * (1.0 if approach == "inward" else -1.0)
    y = np.array([0.0, 0.0, 1.0])
    x = np.cross(y, z)
    return pin.SE3(np.column_stack([x, y, z]), face_centre(face, pitch))


def angle_deg(u, v):
    c = abs(float(np.dot(u, v))) / (np.linalg.norm(u) * np.linalg.norm(v))
    return math.degrees(math.acos(min(1.0, c)))


def on_face(M, face, pitch):
    axis, sign = FACES[face]
    p = M.translation
    z = M.rotation[:, 2]
    dist = abs(p[axis] - sign * pitch / 2.0)
    inside = all(abs(p[k]) <= pitch / 2.0 + 1e-9 for k in range(3) if k != axis)
    ang = angle_deg(z, unit(axis))
    approach = "inward" if float(np.dot(z, inward_normal(face))) > 0 else "outward"
    return dist, inside, ang, approach


def classify(M, pitch, tol_m, tol_deg):
    for face in FACES:
        dist, inside, ang, approach = on_face(M, face, pitch)
        if dist <= tol_m and inside and ang <= tol_deg:
            return face, approach
    return None, None


def inertia_ok(mass, I):
    I = 0.5 * (I + I.T)
    e = np.sort(np.linalg.eigvalsh(I))
    pd = bool(e[0] > 0.0)
    tri = bool(e[0] + e[1] >= e[2] * (1.0 - 1e-9))
    return {"mass": mass, "eigen": [float(v) for v in e], "positive_mass": mass > 0.0,
            "positive_definite": pd, "triangle": tri, "ok": bool(mass > 0.0 and pd and tri)}


def check_links(urdf_text):
    out = []
    for link in ET.fromstring(urdf_text).findall("link"):
        name = link.get("name")
        inertial = link.find("inertial")
        if inertial is None:
            out.append({"name": name, "ok": False, "why": "no inertial"})
            continue
        m = float(inertial.find("mass").get("value"))
        a = inertial.find("inertia")
        g = lambda k: float(a.get(k))
        I = np.array([[g("ixx"), g("ixy"), g("ixz")],
                      [g("ixy"), g("iyy"), g("iyz")],
                      [g("ixz"), g("iyz"), g("izz")]])
        r = inertia_ok(m, I)
        r["name"] = name
        out.append(r)
    return out


def main():
    spec = json.load(open(sys.argv[1]))
    pitch, tol_m, tol_deg = spec["pitch"], spec["tol_m"], spec["tol_deg"]
    text = open(spec["urdf"]).read()
    model = pin.buildModelFromUrdf(spec["urdf"])
    data = model.createData()
    report = {"pinocchio": pin.__version__, "nq": model.nq,
              "joints": [model.names[i] for i in range(1, model.njoints)],
              "links": check_links(text), "bodies": [], "cases": [],
              # The root link and the links fixed to it are merged into the universe's
              # inertia (index 0), which pin.computeTotalMass leaves out: sum them all.
              "total_mass": float(sum(model.inertias[i].mass for i in range(model.njoints)))}
    for i in range(model.njoints):
        Y = model.inertias[i]
        r = inertia_ok(float(Y.mass), np.array(Y.inertia))
        r["name"] = model.names[i]
        report["bodies"].append(r)
    for case in spec["cases"]:
        q = pin.neutral(model)
        res = {"name": case["name"], "frames": {}, "errors": []}
        for jname, v in case["joints"].items():
            if not model.existJointName(jname):
                res["errors"].append(f"no joint {jname}")
                continue
            j = model.joints[model.getJointId(jname)]
            q[j.idx_q] = v
        res["within_limits"] = bool(np.all(q >= model.lowerPositionLimit - 1e-12)
                                    and np.all(q <= model.upperPositionLimit + 1e-12))
        pin.forwardKinematics(model, data, q)
        pin.updateFramePlacements(model, data)
        base = root_placement(case["root"]["face"], case["root"]["approach"], pitch)
        for fname, exp in case["expect"].items():
            if not model.existFrame(fname):
                res["errors"].append(f"no frame {fname}")
                continue
            M = base * data.oMf[model.getFrameId(fname)]
            found, approach = classify(M, pitch, tol_m, tol_deg)
            dist, inside, ang, exp_approach = on_face(M, exp["face"], pitch)
            y_err = angle_deg(M.rotation[:, 1], np.array([0.0, 0.0, 1.0]))
            want_approach = exp.get("approach")
            ok = (found == exp["face"] and dist <= tol_m and ang <= tol_deg
                  and (want_approach is None or want_approach == exp_approach))
            res["frames"][fname] = {
                "found": found, "approach": exp_approach, "plane_err_m": dist,
                "axis_err_deg": ang, "y_err_deg": y_err, "inside": inside,
                "position": [float(v) for v in M.translation], "ok": bool(ok)}
        # Gravity (world -Y, 1000 mg) as read in the given frames (IMU model check).
        res["gravity_mg"] = {}
        for fname in case.get("gravity_frames", []):
            if not model.existFrame(fname):
                res["errors"].append(f"no frame {fname}")
                continue
            M = base * data.oMf[model.getFrameId(fname)]
            g = M.rotation.T @ np.array([0.0, -1000.0, 0.0])
            res["gravity_mg"][fname] = [float(v) for v in g]
        report["cases"].append(res)
    json.dump(report, sys.stdout, indent=1)


if __name__ == "__main__":
    main()
