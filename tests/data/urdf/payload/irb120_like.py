"""Write the IRB 120-like URDF: DH lengths of ABB's product specification, masses and inertias estimated
(solid boxes and cylinders), the arm about 25 kg with its base."""
def cyl(m, r, h, axis):     # solid cylinder, axis 'x'|'y'|'z'
    a = 0.5 * m * r * r; b = m * (3 * r * r + h * h) / 12
    return {"x": (a, b, b), "y": (b, a, b), "z": (b, b, a)}[axis]
def box(m, x, y, z):
    return (m * (y*y + z*z) / 12, m * (x*x + z*z) / 12, m * (x*x + y*y) / 12)
links = [  # name, mass, com, (ixx, iyy, izz)
    ("base_link", 7.0, (0, 0, 0.08), cyl(7.0, 0.09, 0.16, "z")),
    ("link_1", 5.5, (0, 0, 0.21), cyl(5.5, 0.08, 0.16, "z")),
    ("link_2", 5.0, (0, 0, 0.135), box(5.0, 0.09, 0.12, 0.33)),
    ("link_3", 4.0, (0.06, 0, 0.03), box(4.0, 0.16, 0.11, 0.12)),
    ("link_4", 2.0, (0.17, 0, 0), cyl(2.0, 0.045, 0.2, "x")),
    ("link_5", 0.7, (0.012, 0, 0), box(0.7, 0.07, 0.08, 0.06)),
    ("link_6", 0.2, (0.006, 0, 0), cyl(0.2, 0.03, 0.02, "x")),
]
joints = [  # name, parent, child, xyz, axis, lower, upper, effort, velocity
    ("joint_1", "base_link", "link_1", (0, 0, 0), (0, 0, 1), -2.87979, 2.87979, 60, 4.36332),
    ("joint_2", "link_1", "link_2", (0, 0, 0.29), (0, 1, 0), -1.91986, 1.91986, 80, 4.36332),
    ("joint_3", "link_2", "link_3", (0, 0, 0.27), (0, 1, 0), -1.91986, 1.22173, 40, 4.36332),
    ("joint_4", "link_3", "link_4", (0, 0, 0.07), (1, 0, 0), -2.79253, 2.79253, 12, 5.58505),
    ("joint_5", "link_4", "link_5", (0.302, 0, 0), (0, 1, 0), -2.0944, 2.0944, 12, 5.58505),
    ("joint_6", "link_5", "link_6", (0.072, 0, 0), (1, 0, 0), -6.98132, 6.98132, 8, 7.33038),
]
f = lambda v: " ".join(f"{x:.6g}" for x in v)
out = ['<?xml version="1.0"?>',
       "<!-- An ABB IRB 120-like arm written for derive's tests (public domain / 0BSD, licenses/synthetic.LICENSE.txt).",
       "     Kinematics: the DH lengths of ABB's IRB 120 product specification (0.290, 0.270, 0.070, 0.302, 0.072 m),",
       "     joint ranges and speeds of its data sheet (165/110/-110..70/160/120/400 deg; 250/250/250/320/320/420 deg/s).",
       "     Masses (about 25 kg with the base) and inertias are estimates (solid boxes and cylinders), effort limits",
       "     assumed: not ABB's data. Written by irb120_like.py beside it. -->",
       '<robot name="irb120_like">']
for name, m, c, (ixx, iyy, izz) in links:
    out += [f'  <link name="{name}">', "    <inertial>", f'      <origin xyz="{f(c)}" rpy="0 0 0"/>',
            f'      <mass value="{m:g}"/>',
            f'      <inertia ixx="{ixx:.6g}" ixy="0" ixz="0" iyy="{iyy:.6g}" iyz="0" izz="{izz:.6g}"/>',
            "    </inertial>", "  </link>"]
out += ['  <link name="flange"/>']
for name, p, ch, xyz, ax, lo, hi, eff, vel in joints:
    out += [f'  <joint name="{name}" type="revolute">', f'    <parent link="{p}"/>', f'    <child link="{ch}"/>',
            f'    <origin xyz="{f(xyz)}" rpy="0 0 0"/>', f'    <axis xyz="{f(ax)}"/>',
            f'    <limit lower="{lo}" upper="{hi}" effort="{eff}" velocity="{vel}"/>', "  </joint>"]
out += ['  <!-- the flange frame: z along joint 6\'s axis (the tool axis) -->',
        '  <joint name="joint_6-flange" type="fixed">', '    <parent link="link_6"/>', '    <child link="flange"/>',
        '    <origin xyz="0 0 0" rpy="0 1.5707963267948966 0"/>', "  </joint>", "</robot>", ""]
print("\n".join(out), end="")
