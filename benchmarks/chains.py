"""Synthetic serial chains for the scaling benchmark (benchmarks/scaling.py) and the tests.

``snake_urdf(n)`` is the n-joint form of tests' and shared cases' ``snake12``: links of 0.1 m with
alternating pitch (y) and yaw (z) axes, masses falling from 0.48 kg by 0.02 kg a link (floored at
0.1 kg), every joint revolute within +-1.5 rad. ``decimal=True`` writes the same arm with a
SolidWorks-style frame on every joint: ``rpy="1.5708 0 -0.7854"`` and its inverse folded into
the next joint's origin is not possible in URDF, so the decimal arm is its own arm (the axes
rotated by the decimal rotation): what it measures is the cost of the decimals, not the dynamics.
"""
from __future__ import annotations


def snake_urdf(n: int, decimal: bool = False, exact_rpy: bool = False) -> str:
    """The URDF text of an n-joint snake chain (base ``base``, tip ``l<n>``).

    ``decimal``: every joint's origin carries ``rpy="1.5708 0 -0.7854"`` (4-digit decimals as CAD
    exporters write them); ``exact_rpy``: the same frames written to 17 digits (pi/2, -pi/4 as
    floats, the closest a URDF can come to exact), the pair a benchmark compares."""
    links = ['  <link name="base"/>']
    joints = []
    for k in range(1, n + 1):
        mass = max(0.48 - 0.02 * (k - 1), 0.1)
        links.append(f'  <link name="l{k}"><inertial><origin xyz="0.05 0 0"/><mass value="{mass:.2f}"/>'
                     '<inertia ixx="0.0005" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/></inertial></link>')
        xyz = "0 0 0.05" if k == 1 else "0.1 0 0"
        axis = "0 1 0" if k % 2 else "0 0 1"
        rpy = ""
        if decimal:
            rpy = ' rpy="1.5708 0 -0.7854"'
        elif exact_rpy:
            rpy = ' rpy="1.5707963267948966 0 -0.7853981633974483"'
        joints.append(f'  <joint name="j{k}" type="revolute"><parent link="{"base" if k == 1 else f"l{k - 1}"}"/>'
                      f'<child link="l{k}"/><origin xyz="{xyz}"{rpy}/><axis xyz="{axis}"/>'
                      '<limit lower="-1.5" upper="1.5" effort="20" velocity="2"/></joint>')
    return "\n".join(['<?xml version="1.0"?>', f'<robot name="snake{n}">', *links, *joints, "</robot>", ""])
