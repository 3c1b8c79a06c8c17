"""The text of a starter arm file (derive init): its tables and the comments that say where each number comes
from (the URDF's or MJCF's values, the assumptions, W, the observer step, the sample time and its limits, the
payload design)."""
from __future__ import annotations

from fractions import Fraction
from derive.cli.init_numbers import DEFAULT_SPEED, DEFAULT_TRAVEL_SPEED, speed_box


DIGITS = 4                   # significant digits of W as written (derive.control.starter.DIGITS)
T2_DEFAULT = "0.2"


def _num(x: Fraction | None, unit: str) -> str:
    return "none" if x is None else f"{float(x):g} {unit}".rstrip()


def _limits_comment(joint, word: str = "URDF") -> str:
    lim, unit = joint.limits, "m" if not joint.type.rotates else "rad"
    parts = []
    if lim.lower is not None or lim.upper is not None:
        parts.append(f"position [{_num(lim.lower, '')}, {_num(lim.upper, '')}] {unit}")
    if lim.velocity is not None:
        parts.append(f"velocity {_num(lim.velocity, unit + '/s')}")
    if lim.effort is not None:
        parts.append(f"effort {_num(lim.effort, 'N m' if joint.type.rotates else 'N')}")
    return "; ".join(parts) if parts else f"no limits in the {word}"


def _g(x: float) -> str:
    return f"{x:.{DIGITS}g}"


def _string(text: str) -> str:
    """``text`` as a TOML basic string: a link or file name with a quote, a backslash or a control
    character (U+0000-U+001F, U+007F: TOML's backslash-u escape, four hex digits) stays one string."""
    def escape(c: str) -> str:
        if c in '"\\':
            return "\\" + c
        return f"\\u{ord(c):04x}" if ord(c) < 0x20 or ord(c) == 0x7F else c
    return '"' + "".join(escape(c) for c in text) + '"'


def _description(name: str, urdf_name: str, base: str, tip: str) -> str:
    """The arm's description: its name, the URDF file's and the chain's ends, without the names
    that could not stand in a generated C comment or docstring (derive.model.fields.text_problem)."""
    from derive.model.fields import text_problem

    for text in (f"{name} from {urdf_name}, base {base}, tip {tip}", f"{name} from {urdf_name}"):
        if text_problem(text) is None:
            return text
    return f"{name} from a URDF"


def _vector(values) -> str:
    return "[" + ", ".join(repr(float(x)) if x != int(x) else str(int(x)) for x in values) + "]"


def _snap_lines(snap: float) -> list[str]:
    """The [arm] snap_angles line and its comment (derive.cli.init_source.INIT_SNAP)."""
    line = f"snap_angles = {snap:g}"
    return [line + " " * max(1, 32 - len(line)) + "# rad: rpy angles this close to a multiple of pi/2 are that multiple",
            "# (the notes below name them: pi/2 as exporters round it, e.g. 1.5708, 3.7e-06 rad from it); their",
            "# rotations are then exact and derive check's exact proofs cost several times less. Delete this line",
            "# to keep them as written"]


def starter_text(src, name: str, rel: str | None = None, gain=None, notes: tuple[str, ...] = (),
                 substeps: int | None = None, pose=None, loads=None, payload=None, momentum=None,
                 designed: tuple[str, ...] = (), speed_scale: float = 1.0, widening=None) -> str:
    """The arm file for the chain of ``src`` (derive.cli.init_source.Source; see the module
    docstring), naming ``rel`` (the file's path relative to the arm file; default: ``src.path``).
    ``gain``: the derive.control.starter.StarterGain to write (None: a draft whose W is J's
    scale-free placeholder, for reading the chain back). ``notes``: init's own notes (the
    name's), written before the chain's. ``payload``: the [payload] range to write
    (derive.model.payload.PayloadRange), ``momentum``: the momentum observer's gains K when not the
    default, ``designed``: the comment lines of the payload design (derive.control.payload.design),
    ``speed_scale``: the factor (<= 1) on the velocity limits the payload design chose for the speed box,
    ``widening``: the smooth Coulomb law's widths when a joint's were widened (derive.cli.init_numbers.Widening)."""
    chain, found, word = src.found.chain, src.found, src.word
    key, base_key, tip_key = src.keys
    n = chain.n
    box, assumed = speed_box(chain)
    if src.assumed_gravity:
        gravity = ["gravity = 9.81                  # m/s^2, assumption: Earth's",
                   "gravity_direction = [0, 0, -1]  # assumption: the base link's z axis points up"]
    else:
        gravity = [f"gravity = {src.gravity!r}" + " " * max(1, 22 - len(f"{src.gravity!r}"))
                   + f"# m/s^2: the {word}'s <option gravity>",
                   f"gravity_direction = {_vector(src.direction)}  # the {word}'s gravity in the base body's frame"]
    lines = [
        f"# Arm file written by `derive init` from {src.shown}. Values the {word} does not give are",
        "# assumptions, marked as such: check them against your hardware. Then: derive generate <this file>",
    ] + ([f"# {rel or src.path} is the expansion of `{src.xacro}` by the xacro package"] if src.xacro else []) + [
        "",
        "[arm]",
        f"name = {_string(name)}",
        f"description = {_string(_description(name, src.shown, src.base, src.tip))}",
        f"{key} = {_string(rel if rel is not None else str(src.path.resolve()))}",
        f"{base_key} = {_string(src.base)}",
        f"{tip_key} = {_string(src.tip)}",
        *gravity,
        'actuation = "torque"            # u is the motor torque [N m]: B = diag(gear_ratio), no back-EMF',
        "# locked = { joint_name = 0.0 } # hold joints (rad or m); joints off the chain are held at 0",
    ] + ([f"repair_inertia = [{', '.join(map(_string, found.repaired))}]  # their inertias are not "
          "physical: moved to the nearest physical ones (see the notes below)"] if found.repaired else []) + (
        _snap_lines(src.snap) if getattr(src, "snap", None) is not None else []) + [
        "",
        f"# What reading the {word} did:",
    ]
    lines += [f"#   {note}" for note in (*notes, *chain.notes)] or ["#   nothing to note"]
    armature = found.armature or (0,) * n
    for i, (joint, bv, a) in enumerate(zip(chain.joints, found.damping, armature), 1):
        effort = joint.limits.effort
        unit = "N m" if joint.type.rotates else "N"
        rotor = (f"rotor_inertia = {float(a):g}" + " " * max(1, 15 - len(f"{float(a):g}"))
                 + f"# kg m^2: the {word}'s armature (the rotor inertia reflected to the joint)") if a else \
            "rotor_inertia = 0.0             # kg m^2, assumption: no reflected rotor inertia"
        limit = "effort limit" if src.kind == "urdf" else "actuator force limit"
        damping = "<dynamics damping>" if src.kind == "urdf" else "damping"
        lines += [
            "",
            f"[[motor]]  # joint {i}: {joint.name!r} ({joint.type.value}; {_limits_comment(joint, word)})",
            "gear_ratio = 1.0                # assumption: u is the joint torque",
            rotor,
            f"torque_limit = {float(effort):g}" + " " * max(1, 16 - len(f"{float(effort):g}"))
            + f"# {unit}: the {word}'s {limit}; u is clipped to it" if effort is not None and effort > 0
            else f"# torque_limit = 10.0          # {unit}: uncomment to clip u (the {word} gives no effort limit)",
            f"# viscous_friction = {float(bv):g}" + " " * max(1, 10 - len(f"{float(bv):g}"))
            + f"# {unit} s/{'rad' if joint.type.rotates else 'm'}; default: the {word}'s {damping}",
        ]
    speeds = ", ".join(f"{v:g}" for v in box)
    guessed = [str(i) for i, a in enumerate(assumed, 1) if a]
    if guessed:
        source = (f"the {word}'s velocity limits; joint{'s' if len(guessed) > 1 else ''} {', '.join(guessed)}: "
                  f"assumption, {DEFAULT_SPEED:g} rad/s ({DEFAULT_TRAVEL_SPEED:g} m/s if prismatic), the {word} "
                  "gives no velocity limit")
    else:
        source = f"the {word}'s velocity limits"
    if speed_scale != 1.0:
        box = [float(f"{v * speed_scale:.4g}") for v in box]
        speeds = ", ".join(f"{v:g}" for v in box)
        source = f"{speed_scale:.3g} x {source}, what the [payload] range needs (see there)"
    lines += [
        "",
        "[controller]",
        "T1 = 0.0                        # s, minimum prediction time (eq. 14)",
        f"T2 = {T2_DEFAULT}                        # s, assumption: maximum prediction time (eq. 14); "
        "shorter is stiffer",
        f"max_joint_speed = [{speeds}]  # rad/s (m/s prismatic): {source}; derive check certifies the "
        "observer on this box, and the sample-time limits cover it",
    ]
    if gain is None:
        lines.append(f"w = [{', '.join(['1.0'] * n)}]")
        return "\n".join(lines) + "\n"
    lo, hi = gain.rates
    rows = ",\n     ".join("[" + ", ".join(_g(x) for x in row) + "]" for row in gain.W)
    lines += [
        "# The observer gain W (eq. 25; a full n x n W) [N m s/rad, N s/m on a prismatic joint's row: p = W theta'",
        "# is a joint torque, eq. 21-22]: W = omega Jbar" + (f" + rho Jp_bar (rho = {_g(gain.payload_rate)} 1/s, Jp_bar the "
                                                          "payload's joint-space inertia: see [payload])," if gain.payload_rate else ","),
        "# Jbar the mean of J over the joint ranges, so that the observer rates, the eigenvalues of W J^-1",
        f"# (eq. 24), spread only as far as J does: {_g(lo)} ... {_g(hi)} 1/s over the ranges (omega = {_g(gain.omega)} 1/s),",
        ("# what puts the rates' geometric mean at 20 1/s, more than the observer certificate needs on" if gain.floor
         else "# the smallest omega the observer certificate proves on max_joint_speed, with a margin"),
        ("# max_joint_speed" if gain.floor else "#")
        + f" (its decision: {gain.decision.verdict.value}, {gain.decision.cells} cells: the decision derive check makes).",
        "# Replace it by your own, or by w = \"auto\" (derive tune prints the smallest ||W||).",
        f"w = [{rows}]",
    ] + ([f"momentum_gain = [{', '.join(f'{x:.4g}' for x in momentum)}]  # 1/s: the momentum observer's K (r' = K (B d - r)), the "
          "default 50 scaled with W for the payload"] if momentum is not None else []) + _observer_lines(gain) + [
        "",
        "[simulation]",
    ] + _sample_lines(gain)
    if pose is not None:
        theta0, amp = pose
        lines += [
            f"initial_theta = [{', '.join(_g(x) for x in theta0)}]  # rad (m prismatic): the start pose, chosen so that",
            "# the experiment's gravity torques stay within 0.8 of the effort limits, the pose 5 % of each joint's",
            "# travel inside its limits and every pulse inside its joint's range (the zero pose did not:",
            "# derive.cli.init_numbers.starter_pose)",
            'reference_start = "measured"    # y_d starts at the start pose; the pulses are offsets from it',
            f"amplitude = [{', '.join(_g(x) for x in amp)}]  # rad (m prismatic): each joint's pulse, at most 90 deg (half",
            "# the travel of a prismatic joint) and 0.8 of the room between the start and the upper limit",
        ]
    for key, values in (loads or {}).items():
        lines += [
            f"{key} = [{', '.join(_g(x) for x in values)}]  # N m (N prismatic): the default's, at most 5 rad/s^2",
            "# times each joint's inertia at the start pose (a light joint is not thrown by a load of the paper's",
            "# arm's size: derive.cli.init_numbers.starter_loads)",
        ]
    if substeps is not None:
        lines += [
            f"substeps = {substeps}" + " " * max(1, 20 - len(str(substeps)))
            + "# RK4 steps per sample: the plant's stiffest mode at the initial pose (the joints' friction",
            "# as a smooth Coulomb law, its slope over the joint inertia) needs h lambda <= 2.785",
        ]
    if widening is not None:
        lines += _widening_lines(widening, chain)
    if payload is not None:
        c = ", ".join(_g(x) for x in payload.com)
        lines += ["", "[payload]",
                  f"mass = {_g(payload.mass)}" + " " * max(1, 22 - len(_g(payload.mass)))
                  + "# kg: the controller must hold every payload from 0 to this (derive init --payload)",
                  f"com = [{c}]" + " " * max(1, 20 - len(c)) + "# m, in the tip link's frame: the nominal centre of mass",
                  f"com_radius = {_g(payload.com_radius)}" + " " * max(1, 16 - len(_g(payload.com_radius)))
                  + "# m: the centre of mass may lie anywhere within this ball around com",
                  "# inertia = [[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]]  # kg m^2 about the centre of mass "
                  "at mass; default: a solid sphere of 5 cm radius", *designed]
    return "\n".join(lines + [""])


def _widening_lines(w, chain) -> list[str]:
    """The coulomb_smoothing line and why: which joints were widened, from what to what, what the sharp law
    would cost and how to have it back (derive.cli.init_numbers.rk4_substeps)."""
    from derive.cli.init_numbers import MAX_SUBSTEPS
    from derive.model.simspec import COULOMB_SMOOTHING

    def unit(i: int) -> str:
        return "rad/s" if chain.joints[i].type.rotates else "m/s"

    moved = ", ".join(f"'{chain.joints[i].name}' {COULOMB_SMOOTHING:g} -> {w.widths[i]:g} {unit(i)}" for i in w.widened)
    eps = f"{COULOMB_SMOOTHING:g}"
    return [
        f"coulomb_smoothing = [{', '.join(f'{x:g}' for x in w.widths)}]  # rad/s (m/s prismatic): each joint's "
        "width eps",
        "# of the smooth Coulomb law tau_c tanh(theta'/eps), widened where a light joint's heavy friction made the "
        "plant stiff:",
        f"#   {moved}.",
        f"# At eps = {eps} the law's slope tau_c / eps over the joint inertia needs {w.sharp} RK4 substeps per sample",
        f"# (h lambda <= 2.785): about {w.sharp / max(w.substeps, 1):.3g} times the plant's CPU in derive simulate of "
        f"the {w.substeps} substeps here.",
        f"# Each width is the smallest 1-2-5 value that brings them to at most {MAX_SUBSTEPS} (a regularised Coulomb "
        "law's velocity",
        "# threshold, as in Simscape's Rotational Friction block, default 0.1 rad/s: derive.cli.init_numbers).",
        f"# For the sharp law back: coulomb_smoothing = {eps} and substeps = {w.sharp}.",
    ]


def _ms(x: float) -> str:
    return "none" if x == 0 else "any" if x == float("inf") else f"{x * 1e3:.3g} ms"


def _observer_lines(gain) -> list[str]:
    """The controller.observer line and why (derive.control.starter.choose_observer), when the starter
    takes the implicit step."""
    if gain.observer != "implicit":
        return []
    lims = {f: x for o, f, x in gain.stated if o == "explicit" and f in ("dobc", "npid")}
    mine = {f: x for o, f, x in gain.stated if o == "implicit" and f in ("dobc", "npid")}
    return [
        'observer = "implicit"           # the observer step derive generate, simulate, sweep and fmu build (their',
        "# --observer overrides it): backward Euler. With the forward-Euler step (\"explicit\") the sample time",
        f"# would be {gain.explicit_time * 1e3:.3g} ms, below 0.1 ms: W J^-1's fastest rate, "
        f"{_g(gain.rates[1])} 1/s (the rates spread {_g(gain.rates[1] / gain.rates[0])}-fold as J varies",
        f"# over the ranges), limits its DOBC to {_ms(lims.get('dobc', 0))} and NPID to {_ms(lims.get('npid', 0))}; "
        f"the implicit step's are DOBC {_ms(mine.get('dobc', 0))},",
        f"# NPID {_ms(mine.get('npid', 0))}, and MPC and MOM are the same in both (derive show states them all).",
    ]


def _sample_lines(gain) -> list[str]:
    """The sample_time line and its comment: how it was chosen, and why when it is below 0.1 ms."""
    from derive.control.starter import USABLE

    hi = gain.rates[1]
    lines = [f"sample_time = {gain.sample_time:g}" + " " * max(1, 20 - len(f"{gain.sample_time:g}"))
             + "# s: a round value at most 0.45 of each limit estimated from W and the momentum observer's"]
    if gain.observer == "implicit":
        lines.append(f"# gain (the momentum observer's below 2 / K, {gain.momentum_limit * 1e3:.3g} ms; the implicit "
                     "observer step has no 2 / rate bound), at most 2 ms,")
    else:
        lines += [f"# gain (the forward-Euler observer step is stable below 2 / {_g(hi)} 1/s, 0.9 x: "
                  f"{gain.observer_limit * 1e3:.3g} ms;",
                  f"# the momentum observer's below 2 / K, {gain.momentum_limit * 1e3:.3g} ms), at most 2 ms,"]
    step = "the implicit" if gain.observer == "implicit" else "the forward-Euler"
    lines += [f"# and at most half of each limit derive show and derive check state for this file with {step}",
              "# observer step (the sampled loop over the speed box, 0.9 of the largest stable):"]
    lines += _stated_lines(gain.stated)
    if gain.sample_time < USABLE * (1 - 1e-12):
        rows = [(x, o, f) for o, f, x in gain.stated if o == gain.observer and 0 < x < float("inf")]
        x, o, f = min(rows) if rows else (0.0, gain.observer, "?")
        lines += [f"# Below 0.1 ms: {f.upper()}'s limit, {_ms(x)} with the {o} observer step, sets it "
                  "(no observer step allows more);",
                  "# simulate costs about 1 / sample_time steps a second: lower max_joint_speed or W, or raise the "
                  "joints' light inertias"]
    return lines


def _stated_lines(stated) -> list[str]:
    """Comment lines of the sampled loop's limits (StarterGain.stated), per observer step."""
    ms = _ms
    out = []
    for observer, label in (("explicit", "forward-Euler observer step (observer = \"explicit\", the default)"),
                            ("implicit", "backward-Euler step (observer = \"implicit\", --observer implicit)")):
        forms = [(f, x) for o, f, x in stated if o == observer]
        if forms:
            out.append(f"#   {label}: " + ", ".join(f"{f.upper()} {ms(x)}" for f, x in forms))
    return out
