"""Pinocchio's rigid-body dynamics of a URDF robot at given poses, for tests/robot_pinocchio.rs.

    python pinocchio_dynamics.py ROBOT.urdf POSES.json

POSES.json: a JSON list of states {"q": positions, "qd": rates, "qdd": accelerations}, each
a list in the chain's order [rad, rad/s, rad/s^2 or m, m/s, m/s^2] (one per degree of
freedom: a continuous joint's angle, not Pinocchio's (cos, sin) pair). Prints one JSON
object: {"pinocchio": version, "joints": [names in Pinocchio's order], "gravity": [x, y, z],
"poses": [{"M": rows, "g": vector, "dg_dq": rows, "tau": vector}, ...]} with
  M      pinocchio.crba (it fills the upper triangle only: symmetrised here) [kg m^2 ...],
  g      pinocchio.computeGeneralizedGravity [N m or N],
  dg_dq  pinocchio.computeGeneralizedGravityDerivatives [N m/rad ...],
  tau    pinocchio.rnea(q, qd, qdd) [N m or N].

The model is pinocchio.buildModelFromUrdf without a root joint: the root link is fixed to
the universe, fixed joints become frames whose bodies' inertias are appended to the
parent joint's body (the same physics as flexid's merge), joints in depth-first order from
the root (the chain's order). Gravity is Pinocchio's default, -9.81 m/s^2 along z.
"""

import json
import sys

import numpy as np
import pinocchio as pin


def main():
    urdf, poses_file = sys.argv[1], sys.argv[2]
    model = pin.buildModelFromUrdf(urdf)
    data = model.createData()
    with open(poses_file) as f:
        poses = json.load(f)
    if any(j.nv != 1 for j in model.joints[1:]):
        sys.exit("pinocchio_dynamics: not a chain of one-degree-of-freedom joints")
    neutral = pin.neutral(model)
    out = []
    for state in poses:
        angles = np.asarray(state["q"], dtype=float)
        qd = np.asarray(state["qd"], dtype=float)
        qdd = np.asarray(state["qdd"], dtype=float)
        if angles.shape != (model.nv,):
            sys.exit(f"pinocchio_dynamics: pose of {angles.shape} entries, the model has {model.nv} joints")
        # Pinocchio's configuration: a continuous joint is (cos q, sin q) (nq = 2, nv = 1);
        # integrating the angles from the neutral pose gives it for every joint kind.
        q = pin.integrate(model, neutral, angles)
        m = pin.crba(model, data, q).copy()
        m = np.triu(m) + np.triu(m, 1).T
        g = pin.computeGeneralizedGravity(model, data, q).copy()
        dg = pin.computeGeneralizedGravityDerivatives(model, data, q).copy()
        tau = pin.rnea(model, data, q, qd, qdd).copy()
        out.append({"M": m.tolist(), "g": g.tolist(), "dg_dq": dg.tolist(), "tau": tau.tolist()})
    json.dump(
        {
            "pinocchio": pin.__version__,
            # names[0] is the universe
            "joints": list(model.names)[1:],
            "gravity": model.gravity.linear.tolist(),
            "poses": out,
        },
        sys.stdout,
    )


if __name__ == "__main__":
    main()
