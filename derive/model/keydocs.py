"""Every arm-file table and key with its unit, default, range and meaning, as data.

The readers (derive.model.spec, planar, dh, actuators, simspec, sweepspec, payload, override)
hold the authoritative key sets (``ARM_KEYS``, ``LINK_KEYS``, ``simspec.KEYS``, ...) and reject
any other key; this module documents each of those keys for the documentation's arm-file
reference (docs/gen/keys.py renders it at build time). :func:`coverage` compares the two, so a
key added to a reader without a row here, or a row for a key no reader accepts, fails
``make docs`` and tests/test_docs.py. Nothing here is read by the readers: it changes no
behaviour.

A row's ``default`` is ``"required"`` when the key must be given, ``"-"`` when leaving the key
out means "none" (an optional feature), and otherwise the value the reader takes in its place;
``n`` is the number of joints.
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass

REQUIRED = "required"
NONE = "-"


@dataclass(frozen=True)
class Key:
    """One key of an arm-file table: ``unit`` ("" for a pure number or text), ``default``
    (REQUIRED, NONE or a value), ``range`` (what the reader accepts) and ``meaning``."""

    name: str
    unit: str
    default: str
    range: str
    meaning: str


@dataclass(frozen=True)
class Table:
    """One table of an arm file: its TOML ``header``, where the reader keeps its key set
    (``reader``: ``"module:ATTRIBUTE"``, several joined by ``+``; the keys are the attribute's
    keys or items), a one-paragraph ``doc`` and its ``keys``."""

    header: str
    reader: str
    doc: str
    keys: tuple[Key, ...]

    def reader_keys(self) -> frozenset[str]:
        """The keys the reader accepts in this table (imported from the reader's module)."""
        found: set[str] = set()
        for ref in self.reader.split("+"):
            if ref.startswith("="):                      # a literal key the reader adds inline
                found.add(ref[1:])
                continue
            module, attribute = ref.split(":")
            found |= set(getattr(importlib.import_module(module), attribute))
        return frozenset(found)


K = Key
PER_JOINT = "an array of n numbers"

TABLES: tuple[Table, ...] = (
    Table("(top level)", "derive.model.spec:TOP_KEYS",
          "The tables an arm file may hold. The chain comes from exactly one of: `[[link]]` tables (a planar "
          "arm), a `[dh]` table with `[[body]]` tables, or `urdf` / `mjcf` under `[arm]`.", (
              K("arm", "", REQUIRED, "a table", "the arm's name, gravity, actuation and chain source"),
              K("link", "", NONE, "an array of tables, one per joint", "a planar chain: `[[link]]`, base to tip"),
              K("point_mass", "", NONE, "an array of tables", "point masses carried by planar links "
                "(motors, payloads): `[[point_mass]]`"),
              K("dh", "", NONE, "a table", "a Denavit-Hartenberg chain: `[dh]`"),
              K("body", "", NONE, "an array of tables, one per DH row", "the bodies of a DH chain: `[[body]]`"),
              K("motor", "", REQUIRED, "an array of tables, one per joint", "each joint's drive: `[[motor]]`"),
              K("controller", "", REQUIRED, "a table", "the predictive law and the observer (eq. 14-25)"),
              K("simulation", "", "the defaults below", "a table", "the plant and experiment of `derive simulate`"),
              K("sweep", "", NONE, "a table", "the Monte-Carlo study of `derive sweep`"),
              K("body_override", "", NONE, "an array of tables, at most one per joint",
                "replace a URDF or DH body's ten parameters (`derive identify` writes them)"),
              K("payload", "", NONE, "a table", "the payload range the controller is designed for"),
          )),
    Table("[arm]", "derive.model.spec:ARM_KEYS",
          "The arm's name and where its chain comes from.", (
              K("name", "", REQUIRED, "a lowercase C identifier, at most 31 characters",
                "the prefix of the generated code, files, module and CMake target"),
              K("description", "", '""', "one line of printable text, at most 200 characters",
                "a comment in the generated files"),
              K("gravity", "m/s^2", "0", ">= 0", "the magnitude of gravity; 0 for a horizontal arm"),
              K("gravity_direction", "", "[0, -1] (planar), [0, 0, -1] (spatial)",
                "2 numbers (planar) or 3 (spatial), not all 0",
                "the direction of free fall in the base frame ([0, 1]: a ceiling-mounted planar arm)"),
              K("actuation", "", '"voltage"', '"voltage" or "torque"',
                "the default of every `[[motor]]`: a DC motor driven in V, or u a motor torque in N m"),
              K("urdf", "", NONE, "a path relative to the arm file", "take the chain from this URDF"),
              K("base_link", "", REQUIRED + " (URDF)", "a link of the URDF", "the chain's base (`derive init` writes the "
                "root link, or `--base`)"),
              K("tip_link", "", REQUIRED + " (URDF)", "a link below base_link", "the chain's tip (`derive init` writes "
                "the unique deepest leaf, or `--tip`)"),
              K("locked", "rad or m", "0 for every held joint", "a table joint = value",
                "joints held at a value (URDF or MJCF arms); off-chain joints default to 0"),
              K("repair_inertia", "", "false", "true, or an array of link names",
                "move these non-physical URDF inertias to the nearest physical ones"),
              K("snap_angles", "rad", "1e-08", "1e-08 to 0.001 (URDF)",
                "rpy angles this close to a multiple of pi/2 are that multiple (the 1.5708 of CAD exporters: "
                "exact rotations, exact proofs several times cheaper); `derive init` writes it for angles within "
                "1e-4 rad of one"),
              K("mjcf", "", NONE, "a path relative to the arm file", "take the chain from this MJCF "
                "(MuJoCo's compiler reads it)"),
              K("base_body", "", REQUIRED + " (MJCF)", "a body of the MJCF", "the chain's base"),
              K("tip_body", "", REQUIRED + " (MJCF)", "a body below base_body", "the chain's tip"),
          )),
    Table("[[link]]", "derive.model.planar:LINK_KEYS",
          "One table per joint of a planar chain, base to tip; each angle is relative to the previous link "
          "(theta = 0 along +x of the base).", (
              K("length", "m", REQUIRED, "> 0", "the link's length"),
              K("mass", "kg", REQUIRED, ">= 0 (0: massless, while every joint moves some inertia)", "the link's mass"),
              K("com", "m", "length / 2", "any finite number (negative: a counterweight)",
                "the centre of mass, from the joint along the link"),
              K("inertia", "kg m^2", '"uniform_rod" (m l^2 / 12)', '>= 0, or "uniform_rod"',
                "the inertia about the centre of mass"),
              K("viscous_friction", "N m s/rad", "0", ">= 0", "joint friction known to the controller"),
          )),
    Table("[[point_mass]]", "derive.model.planar:PM_KEYS",
          "A mass carried by a planar link: a motor, a payload. Any number of them.", (
              K("link", "", REQUIRED, "1 .. n", "the link that carries it (1-based)"),
              K("distance", "m", REQUIRED, "any finite number", "from that link's joint along the link"),
              K("mass", "kg", REQUIRED, "> 0", "its mass"),
              K("inertia", "kg m^2", "0", ">= 0", "about its own centre"),
              K("label", "", '""', "one line of printable text", "a name for the generated comments"),
          )),
    Table("[dh]", "derive.model.dh:DH_KEYS",
          "A chain from a Denavit-Hartenberg table; angles may be written as fractions of pi (\"pi/2\"), "
          "which are exact.", (
              K("convention", "", REQUIRED, '"standard" or "modified" (Craig)', "the DH convention"),
              K("table", "m, rad", REQUIRED, "one row [a, alpha, d, theta] per joint",
                "a and d in metres, alpha and theta in radians or as \"p*pi/q\""),
              K("joints", "", 'every joint "revolute"', 'an array of n "revolute" or "prismatic"',
                "the joint variable adds to theta (revolute) or d (prismatic)"),
              K("snap_angles", "rad", "1e-08", "1e-08 to 0.001",
                "alpha and theta this close to a multiple of pi/2 are that multiple (a paper's 1.5708 as pi/2)"),
          )),
    Table("[[body]]", "derive.model.dh:BODY_KEYS",
          "One per DH row, in that link's DH frame.", (
              K("mass", "kg", REQUIRED, ">= 0", "the body's mass"),
              K("com", "m", "[0, 0, 0]", "3 finite numbers", "the centre of mass in the link's frame"),
              K("inertia", "kg m^2", "zero", "a symmetric 3 x 3 array, physically consistent",
                "the inertia about the centre of mass"),
          )),
    Table("[[motor]]", "derive.model.actuators:VOLTAGE_KEYS+derive.model.actuators:TORQUE_KEYS+=viscous_friction",
          "One per joint. A voltage drive is a DC motor, tau = gear Kt (u - gear Kv theta') / R, so "
          "B = diag(gear Kt / R) and the back-EMF damping is gear^2 Kt Kv / R (eq. 11-12; armature "
          "inductance neglected). A torque drive has tau = gear u, B = diag(gear) and no back-EMF: "
          "only gear_ratio, rotor_inertia, torque_limit and actuation.", (
              K("actuation", "", "`[arm] actuation`", '"voltage" or "torque"', "this motor's kind of drive"),
              K("torque_constant", "N m/A", REQUIRED + " (voltage)", "> 0", "Kt"),
              K("voltage_constant", "V s/rad", REQUIRED + " (voltage)", ">= 0 (Kt/Kv within 1/2 .. 2 is plausible)",
                "Kv, the back-EMF constant"),
              K("resistance", "ohm", REQUIRED + " (voltage)", "> 0", "the armature resistance Ra"),
              K("gear_ratio", "", "1", "> 0", "gr: direct drive by default"),
              K("rotor_inertia", "kg m^2", "0", ">= 0", "Jm, reflected as gr^2 Jm on J's diagonal"),
              K("voltage_limit", "V", NONE, "> 0", "the amplifier's limit: u is clipped to +-voltage_limit"),
              K("torque_limit", "N m", NONE, "> 0", "torque drives: u is clipped to +-torque_limit"),
              K("viscous_friction", "N m s/rad", "0 (a URDF's <dynamics damping>, an MJCF's damping)", ">= 0",
                "the joint's friction known to the controller (DH, URDF and MJCF arms; planar arms give it "
                "under `[[link]]`)"),
          )),
    Table("[controller]", "derive.model.spec:CONTROLLER_KEYS",
          "The predictive law (eq. 14-19) and the disturbance observer (eq. 21-25).", (
              K("T1", "s", REQUIRED, ">= 0, < T2; a number or an exact fraction \"p/q\"",
                "the start of the prediction horizon [T1, T2] (eq. 14)"),
              K("T2", "s", REQUIRED, "> T1", "the end of the prediction horizon (eq. 14)"),
              K("w", "N m s/rad", REQUIRED, 'n gains w_j > 0, a full invertible n x n W, or "auto"',
                "the observer gain: Chen's W[i][j] = w_j (j <= i, eq. 25), any W, or the smallest "
                "certified one (an SDP on max_joint_speed, observer_rate)"),
              K("C", "", "the identity", "an n x n array", "the output map y = C theta (eq. 13)"),
              K("max_joint_speed", "rad/s (m/s prismatic)", NONE + ' (required with w = "auto")', PER_JOINT + " > 0",
                "the speed box the observer certificate must cover"),
              K("observer_rate", "1/s", "0", ">= 0", "the exponential rate the certificate must give"),
              K("observer_structure", "", '"chen"', '"chen" or "full", only with w = "auto"',
                "the pattern of the synthesised W"),
              K("momentum_gain", "1/s", "50 for every joint", PER_JOINT + " > 0",
                "K of the generalized-momentum observer (form mom)"),
              K("observer", "", '"explicit"', '"explicit" or "implicit"',
                "the observer step generate, simulate, sweep and fmu build unless --observer says otherwise "
                "(forward Euler, or the backward-Euler step of eq. 21)"),
          )),
    Table("[simulation]", "derive.model.simspec:KEYS",
          "What the plant of `derive simulate`, `derive sweep` and the plant FMU has that the controller does "
          "not know, and the paper's experiment (section 5). Every key is optional.", (
              K("duration", "s", "30", "> 0", "simulated time"),
              K("sample_time", "s", "0.002", "> 0", "the controller's sample time (u held: zero-order hold)"),
              K("substeps", "", "4", "a whole number >= 1", "RK4 steps of the plant per sample"),
              K("pulse_period", "s", "30", "> 0", "the period of the reference pulse train"),
              K("amplitude_deg", "deg", "90", "finite", "the pulse amplitude of every joint (section 5.2)"),
              K("amplitude", "rad (m prismatic)", "amplitude_deg for each joint", PER_JOINT,
                "each joint's pulse in its own unit, instead of amplitude_deg (not both)"),
              K("start", "s", "[0, 5, 10, ...]", PER_JOINT + " >= 0", "when each link's pulse train starts"),
              K("coulomb_friction", "N m", "[0.05, 0.01, ...]", PER_JOINT + " >= 0",
                "smoothed Coulomb friction tau_c tanh(theta'/eps), eps each joint's coulomb_smoothing"),
              K("coulomb_smoothing", "rad/s (m/s prismatic)", "[0.01, ...]",
                PER_JOINT + " > 0, or one number > 0 for every joint",
                "the width eps of the smooth Coulomb law tau_c tanh(theta'/eps): its slope tau_c/eps at rest "
                "sets the plant's stiffest mode and so the RK4 substeps (derive init widens it on a light joint "
                "with heavy friction)"),
              K("viscous_friction", "N m s/rad", "[0.01, 0.002, ...]", PER_JOINT + " >= 0",
                "extra viscous friction the controller does not know"),
              K("payload_scale", "", "1.2", ">= 0", "mass (and inertia) factor of the last link's point masses"),
              K("payload_mass", "kg", "0", ">= 0", "a rigid payload on the tip, in the plant only: J + J_p, G + G_p"),
              K("payload_com", "m", "`[payload] com`, else [0, 0, 0]", "3 finite numbers, |payload_com| <= 2 m",
                "the payload's centre of mass in the tip link's frame"),
              K("link_mass_scale", "", "[1, ...]", PER_JOINT + " > 0", "mass (and inertia) factor of each link"),
              K("torque_constant_scale", "", "[1, ...]", PER_JOINT + " > 0", "factor on each motor's Kt"),
              K("voltage_constant_scale", "", "[1, ...]", PER_JOINT + " >= 0", "factor on each motor's Kv"),
              K("resistance_scale", "", "[1, ...]", PER_JOINT + " > 0", "factor on each motor's resistance"),
              K("disturbance", "V (N m torque drives)", "[0.3, 0.1, ...]", PER_JOINT,
                "the unknown constant input disturbance d (eq. 12)"),
              K("velocity_noise", "rad/s", "[0, ...]", PER_JOINT + " >= 0", "tachometer noise standard deviation"),
              K("position_noise", "rad", "[0, ...]", PER_JOINT + " >= 0", "position sensor noise standard deviation"),
              K("seed", "", "1", "a whole number >= 0", "the noise seed"),
              K("tacho_filter_hz", "Hz", "0", ">= 0", "first-order low-pass on the measured theta' (0: none)"),
              K("initial_theta", "rad (m prismatic)", "[0, ...]", PER_JOINT, "the initial joint angles, at rest"),
              K("reference_start", "", '"zero"', '"zero" or "measured"',
                "where y_d starts: at 0 (section 5.2) or at C theta(0), the pulses an offset added to it"),
              K("mujoco_model", "", '"" (the arm\'s own URDF or MJCF)', "a path relative to the arm file",
                "the MJCF or URDF that `--plant mujoco` integrates"),
              K("mujoco_contacts", "", "false", "true or false",
                "MuJoCo's contacts between an MJCF's primitive geoms under `--plant mujoco`"),
          )),
    Table("[sweep]", "derive.model.sweepspec:KEYS",
          "A Monte-Carlo robustness study (`derive sweep`): plants drawn from `[sweep.vary]`, judged by "
          "`[[sweep.criterion]]`.", (
              K("samples", "", "0 (`--samples` gives it)", "a whole number >= 1", "how many plants are drawn"),
              K("seed", "", "1", "a whole number >= 0", "sample i draws from SeedSequence([seed, i]) only"),
              K("controllers", "", '["mpc", "dobc", "npid"]', "a non-empty array of controller names",
                "the forms each sample runs"),
              K("duration", "s", "`[simulation] duration`", "> 0", "each run's simulated time"),
              K("vary", "", "{} (nothing drawn)", "a table parameter = { distribution = ... }",
                "what is drawn: see `[sweep.vary]`"),
              K("criterion", "", "[] (no criterion)", "an array of tables", "pass criteria: see `[[sweep.criterion]]`"),
          )),
    Table("[sweep.vary]", "derive.model.sweepspec:PARAMETERS",
          "Each parameter sets a `[simulation]` key of the sample. A value is `{ distribution = \"uniform\", "
          "low = .., high = .. }`, `{ distribution = \"normal\", mean = .., sd = .. }` or `{ distribution = "
          "\"lognormal\", median = .., sigma = .. }`; normal and lognormal take optional truncation bounds "
          "`low` and `high`.", (
              K("payload_scale", "", NONE, "> 0, one draw per arm", "mass factor of the last link's point masses"),
              K("payload_mass", "kg", NONE, ">= 0, one draw per arm", "a rigid payload on the tip"),
              K("payload_com", "m", NONE, "one draw per component x, y, z; sqrt(3) max(|low|, |high|) <= 2",
                "its centre of mass in the tip link's frame"),
              K("link_mass", "", NONE, "> 0, one draw per joint", "factor on each link's mass (and inertia)"),
              K("coulomb_friction", "", NONE, ">= 0, one draw per joint", "factor on simulation.coulomb_friction"),
              K("viscous_friction", "", NONE, ">= 0, one draw per joint", "factor on simulation.viscous_friction"),
              K("disturbance", "V (N m torque drives)", NONE, "one draw per joint", "the input disturbance d (eq. 12)"),
              K("torque_constant", "", NONE, "> 0, one draw per joint", "factor on the motor's torque constant"),
              K("voltage_constant", "", NONE, ">= 0, one draw per joint", "factor on the motor's voltage constant"),
              K("resistance", "", NONE, "> 0, one draw per joint", "factor on the motor's resistance"),
              K("velocity_noise", "rad/s", NONE, ">= 0, one draw per joint", "tachometer noise standard deviation"),
              K("position_noise", "rad", NONE, ">= 0, one draw per joint", "position noise standard deviation"),
          )),
    Table("[[sweep.criterion]]", "derive.model.sweepspec:CRITERION_KEYS",
          "A sample passes when every criterion holds: `metric <= max` on every link, or on `link`.", (
              K("metric", "", REQUIRED, "one of rms_error, max_error, steady_state_error, control_effort, "
                "saturated_time", "the metric judged"),
              K("max", "the metric's", REQUIRED, "a finite number", "its largest passing value"),
              K("link", "", "every link", "1 .. n", "the link it applies to"),
          )),
    Table("[payload]", "derive.model.payload:KEYS",
          "The range of payloads the controller is designed for: every payload from 0 to `mass` with its centre "
          "of mass within `com_radius` of `com`, a rigid body fixed to the tip link (`derive init --payload` "
          "writes it).", (
              K("mass", "kg", REQUIRED, ">= 0", "the largest payload"),
              K("com", "m", "[0, 0, 0]", "3 finite numbers; |com| + com_radius <= 2 m",
                "the nominal centre of mass in the tip link's frame"),
              K("com_radius", "m", "0", ">= 0", "the centre of mass may lie anywhere within this ball around com"),
              K("inertia", "kg m^2", "a solid sphere of 5 cm radius", "symmetric, positive definite, a possible "
                "mass distribution", "about the centre of mass at `mass` (scaled with the mass below it)"),
          )),
    Table("[[body_override]]", "derive.model.override:KEYS",
          "URDF and DH arms: replaces the ten parameters of the body a joint moves, in the joint's frame (URDF: "
          "its child link's), after merging; at most one per joint; a planar arm refuses it.", (
              K("joint", "", REQUIRED, "a moving joint's name, or its number (1-based)", "whose body this replaces"),
              K("mass", "kg", REQUIRED, ">= 0", "the body's mass"),
              K("first_moment", "kg m", REQUIRED, "3 finite numbers", "h = m c in the joint's frame"),
              K("inertia", "kg m^2", REQUIRED, "a symmetric 3 x 3 array; the pseudo-inertia positive semidefinite",
                "about the joint frame's origin"),
          )),
)


def coverage() -> list[str]:
    """Every disagreement between TABLES and the readers' key sets, one line each (empty: none)."""
    problems = []
    for table in TABLES:
        documented = [k.name for k in table.keys]
        accepted = table.reader_keys()
        for name in sorted(accepted - set(documented)):
            problems.append(f"{table.header}: key {name!r} is read ({table.reader}) but not documented")
        for name in sorted(set(documented) - accepted):
            problems.append(f"{table.header}: key {name!r} is documented but no reader accepts it")
        if len(documented) != len(set(documented)):
            problems.append(f"{table.header}: a key is documented twice")
    return problems
