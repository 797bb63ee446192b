"""Generates ur3.urdf: a Universal Robots UR3 (CB3) from the manufacturer's published data.

Run by hand (`python models/make_ur3_urdf.py`) after changing a number; the URDF is committed.

Source (kinematics and masses): Universal Robots, "Parameters for calculations of kinematics
and dynamics" (support article 45257, www.universal-robots.com/articles/ur/
application-installation/dh-parameters-for-calculations-of-kinematics-and-dynamics/), table
"UR3": standard Denavit–Hartenberg parameters

    joint   a [m]      d [m]     alpha [rad]   link mass [kg]   centre of mass [m], in DH frame i
    1       0          0.1519    π/2           2.0              (0, -0.02, 0)
    2      -0.24365    0         0             3.42             (0.13, 0, 0.1157)
    3      -0.21325    0         0             1.26             (0.05, 0, 0.0238)
    4       0          0.11235   π/2           0.8              (0, 0, 0.01)
    5       0          0.08535  -π/2           0.8              (0, 0, 0.01)
    6       0          0.0819    0             0.35             (0, 0, -0.02)

with the controller's joint angles as the DH θ (no offsets): q = 0 is the arm stretched out
horizontally, q = (0, -π/2, 0, -π/2, 0, 0) upright. UR publishes no rotational inertia; each
link gets that of a uniform solid cylinder (radius `RADIUS`) about its centre of mass, along
the link for the two long links and along the joint axis for the others. These are a prior
for identification, not a claim about the real arm. The base is welded to the world with z up
(gravity along -z), as the logs in ../shared/realdata/ur3 were recorded.

DH → URDF. DH frame i is frame i-1 moved by ``Rz(θ_i)·Tz(d_i)·Tx(a_i)·Rx(α_i)``. A URDF joint
applies its motion *after* its fixed origin, so link i's URDF frame is DH frame i-1 rotated by
θ_i about z (joint i's axis), and the fixed part ``Tz(d_i)·Tx(a_i)·Rx(α_i)`` is the origin of
joint i+1 (and of the `tool0` frame after joint 6). Link i's centre of mass and inertia,
given in DH frame i, are mapped into its URDF frame by that fixed part.
"""

from pathlib import Path

import numpy as np

A = [0.0, -0.24365, -0.21325, 0.0, 0.0, 0.0]
D = [0.1519, 0.0, 0.0, 0.11235, 0.08535, 0.0819]
ALPHA = [np.pi / 2, 0.0, 0.0, np.pi / 2, -np.pi / 2, 0.0]
MASS = [2.0, 3.42, 1.26, 0.8, 0.8, 0.35]
COM_DH = [(0.0, -0.02, 0.0), (0.13, 0.0, 0.1157), (0.05, 0.0, 0.0238),
          (0.0, 0.0, 0.01), (0.0, 0.0, 0.01), (0.0, 0.0, -0.02)]
RADIUS = 0.045  # m, about the UR3's link tubes and joint housings
# Cylinder length (m) and its axis in DH frame i: links 2 and 3 run along x_i (|a_i|).
CYLINDER = [(0.15, 1), (0.24365, 0), (0.21325, 0), (0.11, 1), (0.11, 1), (0.05, 2)]
# UR3 joint limits (±2π for every joint on the CB3; joint 6 infinite), speeds (rad/s: 180°/s
# for the base joints, 360°/s for the wrists) and rated torques (N·m: 56, 56, 28, 12, 12, 12)
# from the UR3 technical specifications.
VELOCITY = [3.14, 3.14, 3.14, 6.28, 6.28, 6.28]
EFFORT = [56.0, 56.0, 28.0, 12.0, 12.0, 12.0]


def dh_fixed(i):
    """Tz(d_i)·Tx(a_i)·Rx(α_i) as a 4×4 transform."""
    c, s = np.cos(ALPHA[i]), np.sin(ALPHA[i])
    T = np.eye(4)
    T[:3, :3] = [[1, 0, 0], [0, c, -s], [0, s, c]]
    T[:3, 3] = [A[i], 0.0, D[i]]
    return T


def cylinder_inertia(m, r, h, axis):
    """Inertia (3×3, about the centre) of a solid cylinder of length h along `axis`."""
    across = m * (3 * r**2 + h**2) / 12
    diag = np.full(3, across)
    diag[axis] = m * r**2 / 2
    return np.diag(diag)


def rpy(R):
    """Roll-pitch-yaw (URDF's fixed-axis x-y-z) of a rotation matrix."""
    pitch = np.arcsin(-np.clip(R[2, 0], -1, 1))
    if abs(np.cos(pitch)) < 1e-12:
        return 0.0, pitch, np.arctan2(-R[0, 1], R[1, 1])
    return np.arctan2(R[2, 1], R[2, 2]), pitch, np.arctan2(R[1, 0], R[0, 0])


def fmt(v):
    return " ".join(f"{0.0 if abs(x) < 1e-15 else x:.10g}" for x in v)


def origin(T):
    return f'<origin xyz="{fmt(T[:3, 3])}" rpy="{fmt(rpy(T[:3, :3]))}"/>'


def link(i):
    F = dh_fixed(i)
    com = F[:3, :3] @ np.array(COM_DH[i]) + F[:3, 3]
    h, axis = CYLINDER[i]
    inertia = F[:3, :3] @ cylinder_inertia(MASS[i], RADIUS, h, axis) @ F[:3, :3].T
    entries = {"ixx": (0, 0), "ixy": (0, 1), "ixz": (0, 2), "iyy": (1, 1), "iyz": (1, 2),
               "izz": (2, 2)}
    inertia_attributes = " ".join(f'{k}="{inertia[ij]:.10g}"' for k, ij in entries.items())
    return f"""  <link name="link_{i + 1}">
    <inertial>
      <origin xyz="{fmt(com)}" rpy="0 0 0"/>
      <mass value="{MASS[i]}"/>
      <inertia {inertia_attributes}/>
    </inertial>
  </link>"""


def joint(i):
    parent = "base_link" if i == 0 else f"link_{i}"
    T = np.eye(4) if i == 0 else dh_fixed(i - 1)
    return f"""  <joint name="joint_{i + 1}" type="revolute">
    <parent link="{parent}"/>
    <child link="link_{i + 1}"/>
    {origin(T)}
    <axis xyz="0 0 1"/>
    <limit lower="{-2 * np.pi:.6f}" upper="{2 * np.pi:.6f}" velocity="{VELOCITY[i]}"
           effort="{EFFORT[i]}"/>
  </joint>"""


def urdf():
    parts = ['<?xml version="1.0"?>',
             "<!-- Generated by models/make_ur3_urdf.py from Universal Robots' published UR3",
             "     DH parameters, link masses and centres of mass (see that script). -->",
             '<robot name="ur3">',
             '  <link name="world"/>',
             '  <link name="base_link"/>',
             '  <joint name="world_weld" type="fixed">',
             '    <parent link="world"/>',
             '    <child link="base_link"/>',
             '    <origin xyz="0 0 0" rpy="0 0 0"/>',
             "  </joint>"]
    for i in range(6):
        parts += [link(i), joint(i)]
    parts += ['  <link name="tool0"/>',
              '  <joint name="tool0_weld" type="fixed">',
              '    <parent link="link_6"/>',
              '    <child link="tool0"/>',
              f"    {origin(dh_fixed(5))}",
              "  </joint>",
              "</robot>", ""]
    return "\n".join(parts)


if __name__ == "__main__":
    out = Path(__file__).with_name("ur3.urdf")
    out.write_text(urdf())
    print(f"wrote {out}")
