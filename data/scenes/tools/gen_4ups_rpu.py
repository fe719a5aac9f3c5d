#!/usr/bin/env python3
"""Writes the scene of the 4-UPS/RPU parallel mechanism (Chen et al., Trans. CSAM 54(12), 2023).

The paper gives masses, inertias and a few radii (its Table 1) but not the drawing of the geometry
(its Fig. 5 is missing). This script reconstructs a geometry consistent with every number it gives
and with its constraint count, writes each choice into the scene's header, and keeps the
alternatives selectable from the command line:

  --layout square    limbs 2-5 at 45, 135, 225, 315 degrees around the base and platform (default:
                     the likelier reading; S2 and S5 on the +Y side as the paper's results need)
  --layout pentagon  all five limbs at 72-degree spacing, limb 1 at 0 degrees (+Y)
  --u1-sign +1|-1    U1 at platform-local (+-0.059, 0.229, 0) (the paper does not give the sign)
  --omega W          drive angular frequency of trajectory (69), rad/s (paper: 1.57, 3.14, 4.71)
  --clearance ideal|spherical|mixed
                     which joints have clearance: none, S2 and S5, or S2, S5 and R1 (the paper's
                     three cases)
  --size C           clearance in m (paper: 2e-4, 3e-4, 4e-4); R1's radial and axial clearance
                     are equal, as in the paper
  --friction CF      friction coefficient c_f (paper: 0.04, 0.05, 0.06)
  --gravity hanging|standing
                     gravity along +X (default: the mechanism hangs from its base, or global X
                     points down) or along -X (it stands on its base, X up: the first reading,
                     kept for comparison). Why hanging: analyses/4ups-rpu/gravity-screen.toml and
                     lever.py, summarised in book/src/results/reproduction.md ("Which way is down?")

  --start free|closed
                     how the clearance joints start (their blocks' `start`): free (default: the
                     assembly closes the loops through the ideal joints only, and the joints with
                     clearance start where that puts them, their journals at rest in the middle of
                     the gap but moving at up to 1.5 cm/s relative to their housings, as every
                     result of book/src/results/reproduction.md was computed) or closed (assembled
                     as ideal joints, then released; book/src/reference/scene.md, "Starting
                     clearance joints")

Frames (all SI): global X vertical, gravity +9.81 m/s^2 along X (--gravity hanging) or -9.81
(--gravity standing). Base points lie in the
plane X = 0 at (0, r cos t, r sin t); the platform moves near X = 1.2 m with its normal (its local
x) along global X. Platform centre trajectory (69): X = 1.21 - 0.03 cos(w t), Y = 0.03 sin(w t),
Z = 0, constant orientation; the five prismatic strokes are the leg lengths of that motion
(profile kind "leg_length").

Usage: python3 gen_4ups_rpu.py [options] > ../4ups-rpu.toml
"""
import argparse
import math

# Table 1 of the paper.
TELE = dict(mass=8.57, length=0.840, ixx=1.71e-3, iyy=0.550, izz=0.550)
SWING = dict(mass=10.54, length=0.760, ixx=6.50e-3, iyy=0.643, izz=0.643)
PLATFORM = dict(mass=18.64, ixx=0.458, iyy=0.237, izz=0.237)
R_P = 0.645   # base radius of U2-U5 (m)
L_R1 = 0.710  # offset of R1 on the base (m)
R_11 = 0.202  # platform radius of S2-S5 (m)
U1X, U1Y = 0.059, 0.229  # U1 on the platform (m)
# Table 2 of the paper: materials, contact and friction parameters, clearance-joint dimensions.
E, NU, CE = 207e9, 0.3, 0.9
V0, V1 = 1e-4, 1e-2
BALL_R = 0.015                 # ball radius of S2, S5 (m)
R_B1, R_B2, L_B = 0.010, 0.014, 0.180  # R1 bushing inner radius, end-face radius, length (m)
# Trajectory (69).
XC, AMP = 1.21, 0.03


def sub(a, b):
    return [a[i] - b[i] for i in range(3)]


def add(a, b):
    return [a[i] + b[i] for i in range(3)]


def scale(a, s):
    return [x * s for x in a]


def norm(a):
    return math.sqrt(sum(x * x for x in a))


def unit(a):
    n = norm(a)
    return [x / n for x in a]


def cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def f(x):
    return repr(float(x))


def vec(v):
    return "[" + ", ".join(f(x) for x in v) + "]"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--layout", choices=["square", "pentagon"], default="square")
    ap.add_argument("--u1-sign", type=float, choices=[1.0, -1.0], default=1.0)
    ap.add_argument("--omega", type=float, default=3.14)
    ap.add_argument("--periods", type=float, default=2.0)
    ap.add_argument("--clearance", choices=["ideal", "spherical", "mixed"], default="ideal")
    ap.add_argument("--size", type=float, default=3e-4)
    ap.add_argument("--friction", type=float, default=0.05)
    ap.add_argument("--gravity", choices=["hanging", "standing"], default="hanging")
    ap.add_argument("--start", choices=["free", "closed"], default="free")
    ap.add_argument("--name", default=None)
    a = ap.parse_args()
    if not a.size > 0:
        ap.error("--size must be positive")
    if a.name is None:
        a.name = "4ups-rpu" if a.clearance == "ideal" else f"4ups-rpu-{a.clearance}"
    with_clearance = {"ideal": set(), "spherical": {"S2", "S5"}, "mixed": {"S2", "S5", "R1"}}[a.clearance]

    angles = [45.0, 135.0, 225.0, 315.0] if a.layout == "square" else [72.0, 144.0, 216.0, 288.0]
    p0 = [XC - AMP, 0.0, 0.0]  # platform centre at t = 0
    out = []
    w = out.append
    kind_text = {"ideal": "ideal joints", "spherical": "clearance in S2 and S5",
                 "mixed": "clearance in S2, S5 and R1"}[a.clearance]
    w(f"# 4-UPS/RPU parallel mechanism, {kind_text}; generated by data/scenes/tools/gen_4ups_rpu.py")
    w(f"#   options: --layout {a.layout} --u1-sign {a.u1_sign:+.0f} --omega {a.omega} --periods {a.periods}"
      f" --clearance {a.clearance} --size {a.size} --friction {a.friction} --gravity {a.gravity}"
      + (f" --start {a.start}" if a.clearance != "ideal" else ""))
    w("#")
    w("# Source: Chen, Guo, Wang, Zhao, Trans. CSAM 54(12):431-448 (2023), Table 1 and trajectory (69).")
    w("# Geometry the paper leaves out (its Fig. 5 is missing), reconstructed here:")
    w("# - global X is vertical (the platform's largest inertia is about its local x, and the platform")
    if a.gravity == "hanging":
        w("#   centre sits at X = 1.21 m); gravity +9.81 m/s^2 along X: the mechanism hangs from its base")
        w("#   (or X points down). The paper gives no direction; this one is chosen because, with it, the")
        w("#   ideal joints' reactions fall inside the paper's section-2.6 bands (S2 219-238 N against")
        w("#   181-257 N, R1 581-618 N against 517-605 N), the platform drifts to +Y as the paper says,")
        w("#   and the contacts of S2, S5 and R1 settle; with gravity along -X (--gravity standing) the")
        w("#   reactions span 27-480 N and 203-966 N, the drift is -Y and the balls rattle for good.")
        w("#   Evidence: analyses/4ups-rpu/gravity-screen.toml and lever.py; book/src/results/reproduction.md,")
        w("#   section \"Which way is down?\";")
    else:
        w("#   centre sits at X = 1.21 m); gravity -9.81 m/s^2 along X: the mechanism stands on its base.")
        w("#   This was the first reading; the default is now --gravity hanging (+9.81 along X), which")
        w("#   the paper's reactions, drift and settled contacts support (book/src/results/reproduction.md, section")
        w("#   \"Which way is down?\"). Kept for comparison and for the results computed with it while")
        w("#   it was the default (the section-3 bifurcation and chaos studies of that report);")
    w("# - R1 on the base at (0, 0.710, 0) with its axis along Z, so limb 1 (R1-P1-U1) moves in the X-Y")
    w("#   plane; U1's first axis (on telescopic rod 1) is parallel to Z, its second (on the platform)")
    w("#   normal to Z and to the leg in the initial pose;")
    w(f"# - U2..U5 on the base at (0, r_p cos t, r_p sin t), S2..S5 on the platform at local")
    w(f"#   (0, r_11 cos t, r_11 sin t), t = {', '.join(f'{x:g}' for x in angles)} deg for limbs 2..5")
    w(f"#   ({a.layout} layout; the alternative is --layout {'pentagon' if a.layout == 'square' else 'square'});")
    w("#   S2 and S5 lie on the +Y side, as the paper's results (platform drifting to +Y) require;")
    w(f"# - U1 on the platform at local ({a.u1_sign * U1X:+.3f}, {U1Y}, 0) (sign unknown; --u1-sign flips it);")
    w("#   of the four layouts (square or pentagon, U1 at +0.059 or -0.059 m) the square one with U1")
    w("#   at +0.059 m is the default: with gravity along +X only it settles near the paper's loads")
    w("#   (S2 176 N, R1 520 N against about 230 and 580 N; analyses/4ups-rpu/geometry.toml,")
    w("#   book/src/results/reproduction.md, section \"The reconstructed geometries\");")
    w("# - each U joint on the base has its first axis normal to the leg and to X, the second")
    w("#   axis (on the swing rod) along leg x first axis; rods have x along the leg, centre of mass at")
    w("#   mid-length: swing rod 0.38 m from the base joint, telescopic rod 0.42 m from the platform joint;")
    w("# - each prismatic stroke is the distance from the base joint centre to the platform joint centre")
    w("#   along the leg, prescribed by the leg length of trajectory (69) (profile kind leg_length).")
    w("# Constraint count: 62 joint rows on 66 coordinates (4 DOF) plus 5 drives: one redundant drive.")
    w("# Joints with clearance (--clearance ideal | spherical | mixed) lose their rows: S2 and S5 three")
    w("# each, R1 five; the mixed case keeps 51 joint rows plus 5 drives, 56 equations as in the paper.")
    w("# Clearance joints (Table 2): E = 207 GPa, nu = 0.3 on both sides; stiffness from the paper's")
    w("# point-contact formula (49) (1.326e11 N/m^1.5 for S2/S5 and 8.62e10 for R1 at c = 0.3 mm);")
    w("# Lankarani-Nikravesh law, c_e = 0.9; Ambrosio friction, v0 = 1e-4, v1 = 1e-2 m/s.")
    if a.clearance != "ideal":
        w(f'# Start: start = "{a.start}" in each clearance block. The paper does not say how its runs start;')
        if a.start == "free":
            w("# the assembly closes the loops through the ideal joints, and the joints with clearance start")
            w("# concentric but with the velocities that projection leaves them (journals moving at up to")
            w("# 1.5 cm/s relative to their housings). Every result of book/src/results/reproduction.md was")
            w('# computed so; start = "closed" (--start closed) assembles them as ideal joints first, which')
            w("# moves the section-2 settling times by -1.2 to +0.2 s (still 3.9-5.6 s against the paper's")
            w('# 0.5-0.8 s) and the settled forces by at most 0.2 % (reproduction.md, "Starting closed").')
        else:
            w("# the clearance joints are assembled as ideal joints, then released (no relative velocity).")
    w("# S2, S5: ball (radius 15 mm) on the platform, socket on the telescopic rod. R1: bushing on the")
    w("# base (inner radius 10 mm, end-face radius 14 mm, length 180 mm), journal on swing rod 6,")
    w("# radial clearance = axial clearance per side (the paper's choice). The joints start centred")
    w("# (ball and journal concentric with zero eccentricity) with the ideal mechanism's velocities.")
    w("")
    w(f'name = "{a.name}"')
    size_text = "" if a.clearance == "ideal" else f", c = {a.size * 1e3:g} mm, c_f = {a.friction}"
    w(f'description = "4-UPS/RPU, {kind_text}{size_text}, {a.layout} layout, U1 sign {a.u1_sign:+.0f}, omega = {a.omega} rad/s"')
    w("gravity = [9.81, 0.0, 0.0]" if a.gravity == "hanging" else "gravity = [-9.81, 0.0, 0.0]")
    w("")
    base_pts = {}
    base_axes = {"Z": [0.0, 0.0, 1.0]}
    limbs = []  # (index, base point, platform local point, platform global point, kind)
    b1 = [0.0, L_R1, 0.0]
    u1_local = [a.u1_sign * U1X, U1Y, 0.0]
    limbs.append((1, b1, u1_local, add(p0, u1_local), "RPU"))
    for i, t in zip(range(2, 6), angles):
        tr = math.radians(t)
        b = [0.0, R_P * math.cos(tr), R_P * math.sin(tr)]
        s_local = [0.0, R_11 * math.cos(tr), R_11 * math.sin(tr)]
        limbs.append((i, b, s_local, add(p0, s_local), "UPS"))

    bodies = []
    joints = []
    drives = []
    plat_points = {}
    plat_axes = {}
    for i, b, pl, pg, kind in limbs:
        u = unit(sub(pg, b))
        length = norm(sub(pg, b))
        if kind == "RPU":
            z = [0.0, 0.0, 1.0]
            y = cross(z, u)
            base_pts["R1"] = b
            first_axis_global = z
        else:
            y = unit(cross([1.0, 0.0, 0.0], u))  # U first axis: normal to the leg and to X
            base_pts[f"U{i}"] = b
            base_axes[f"U{i}"] = y
            first_axis_global = y
        swing = f"swing{i + 5}"
        tele = f"rod{i}"
        top = "U1" if kind == "RPU" else f"S{i}"
        bot = "R1" if kind == "RPU" else f"U{i}"
        for name, spec, com, pts in (
            (swing, SWING, add(b, scale(u, SWING["length"] / 2)), {bot: [-SWING["length"] / 2, 0, 0]}),
            (tele, TELE, sub(pg, scale(u, TELE["length"] / 2)), {top: [TELE["length"] / 2, 0, 0]}),
        ):
            bodies.append((name, spec, com, u, y, pts))
        plat_points[top] = pl
        if kind == "RPU":
            joints.append((bot, "revolute", "ground", swing, bot, bot, "Z", "z"))
            joints.append((f"P{i}", "prismatic", swing, tele, bot, top, "x", "x"))
            plat_axes["U1"] = cross([0.0, 0.0, 1.0], u)  # normal to Z and to the leg (platform local = global at t = 0)
            joints.append((top, "universal", tele, "platform", top, top, "z", "U1"))
        else:
            joints.append((bot, "universal", "ground", swing, bot, bot, bot, "z"))
            joints.append((f"P{i}", "prismatic", swing, tele, bot, top, "x", "x"))
            joints.append((top, "spherical", tele, "platform", top, top, None, None))
        drives.append((f"drive{i}", f"P{i}", b, add([XC, 0.0, 0.0], pl), length))

    w("[ground]")
    w("points = { " + ", ".join(f"{k} = {vec(v)}" for k, v in base_pts.items()) + " }")
    w("axes = { " + ", ".join(f"{k} = {vec(v)}" for k, v in base_axes.items()) + " }")
    w("")
    for name, spec, com, u, y, pts in bodies:
        w("[[bodies]]")
        w(f'name = "{name}"')
        w(f"mass = {spec['mass']}")
        w(f"inertia = {{ ixx = {spec['ixx']}, iyy = {spec['iyy']}, izz = {spec['izz']} }}")
        w(f"position = {vec(com)}")
        w(f"orientation = {{ x = {vec(u)}, y = {vec(y)} }}")
        w("points = { " + ", ".join(f"{k} = {vec(v)}" for k, v in pts.items()) + " }")
        w("axes = { x = [1.0, 0.0, 0.0], z = [0.0, 0.0, 1.0] }")
        w("")
    w("[[bodies]]")
    w('name = "platform"')
    w(f"mass = {PLATFORM['mass']}")
    w(f"inertia = {{ ixx = {PLATFORM['ixx']}, iyy = {PLATFORM['iyy']}, izz = {PLATFORM['izz']} }}")
    w(f"position = {vec(p0)}")
    w("points = { " + ", ".join(f"{k} = {vec(v)}" for k, v in plat_points.items()) + " }")
    w("axes = { " + ", ".join(f"{k} = {vec(v)}" for k, v in plat_axes.items()) + " }")
    w("")
    for name, kind, ba, bb, pa, pb, aa, ab in joints:
        w("[[joints]]")
        w(f'name = "{name}"')
        w(f'kind = "{kind}"')
        w(f'body_a = "{ba}"')
        w(f'body_b = "{bb}"')
        w(f'point_a = "{pa}"')
        w(f'point_b = "{pb}"')
        if aa is not None:
            w(f'axis_a = "{aa}"')
            w(f'axis_b = "{ab}"')
        if name in with_clearance:
            w("[joints.clearance]")
            if kind == "spherical":
                w(f"ball_radius = {BALL_R}")
                w(f"radial_clearance = {a.size!r}")
            else:
                w('model = "spatial"')
                w(f"bushing_radius = {R_B1}")
                w(f"radial_clearance = {a.size!r}  # journal radius = bushing radius - clearance")
                w(f"bushing_length = {L_B}")
                w(f"face_radius = {R_B2}")
                w(f"axial_clearance = {a.size!r}")
            w(f'normal = {{ law = "lankarani_nikravesh", youngs_modulus = {E:g}, poisson_ratio = {NU}, restitution = {CE} }}')
            w(f'friction = {{ law = "ambrosio", coefficient = {a.friction}, v0 = {V0:g}, v1 = {V1:g} }}')
            w(f'start = "{a.start}"  # see the header, "Start"')
        w("")
    for name, joint, anchor, center, length in drives:
        w("[[drives]]")
        w(f'name = "{name}"')
        w(f'joint = "{joint}"')
        w(f"# leg length {length:.6f} m at t = 0")
        w(f"profile = {{ kind = \"leg_length\", anchor = {vec(anchor)}, center = {vec(center)}, "
          f"cos_amplitude = [{f(-AMP)}, 0.0, 0.0], sin_amplitude = [0.0, {f(AMP)}, 0.0], omega = {f(a.omega)} }}")
        w("")
    w("[solver]")
    w('integrator = "rk4"')
    w("step = 1e-4")
    w("baumgarte_alpha = 5.0")
    w("baumgarte_beta = 5.0")
    w(f"periods = {a.periods}")
    w("")
    w("[output]")
    w("interval = 1e-3")
    print("\n".join(out))


if __name__ == "__main__":
    main()
