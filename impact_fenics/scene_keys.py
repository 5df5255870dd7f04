"""The keys of a scene file, in one table: name, kind, unit, default and a one-line meaning.

The scene reader (:mod:`impact_fenics.scene_file`) takes from here the keys a
table may hold, how each value is checked and its default; the documentation
generator (:mod:`impact_fenics.docs_pages`) writes ``docs/scenes.md`` from the
same table. A key added here is both accepted and documented; a key missing
here is refused. The keys of each material model are those its classes state
(``parameters``, :mod:`impact_fenics.materials.parameters`), taken from the
registry ``impact_fenics.materials.MODELS``. Pure data: no dolfinx, no mesh.

Kinds of value (how the reader checks them):

    number    a finite int or float            positive  a number > 0
    count     an integer >= 1                  flag      true or false
    text      a non-empty string (``choices``: one of them)
    pair      two finite numbers [a, b]        breaks    [[r (m), intervals], ...]
    list      a list of ``choices``            stiffness a number > 0 or one of ``choices``
    table / tables / array   a sub-table [name], named tables [name.NAME], [[name]]

Units are SI; ``-`` marks a dimensionless number.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from .materials import MODELS as MATERIAL_MODELS
from .materials.parameters import CLASS_DEFAULT, REQUIRED  # REQUIRED: a key that must be given


@dataclass(frozen=True)
class Key:
    """One key of a scene table. ``groups``: the variants of the table that accept it
    (empty: every variant), e.g. the mesh generators that take a parameter."""

    name: str
    kind: str
    unit: str
    default: Any
    what: str
    choices: tuple[str, ...] = ()
    groups: tuple[str, ...] = ()
    default_text: str = ""  # the default in words, when the reader computes it
    note: str = ""  # more for the reference (not quoted in error messages)

    @property
    def described(self) -> str:
        """The meaning with its unit, as error messages quote it."""
        return self.what if self.unit in ("", "-") else f"{self.what} ({self.unit})"


@dataclass(frozen=True)
class Section:
    """A table of the scene file: its TOML form, what it is, its keys and its variants."""

    name: str        # the key of the top level ("top" for the top level itself)
    toml: str        # how it is written: [mesh], [materials.NAME], [[contact]]
    what: str        # one paragraph for the reference
    keys: tuple[Key, ...]
    variants: str = ""  # how the variant (the groups) of an entry is chosen, for the reference

    def key(self, name: str, groups: tuple[str, ...] = ()) -> Key:
        """The key ``name`` (of the variant ``groups``, when two variants name a key alike)."""
        for k in self.keys:
            if k.name == name and (not groups or not k.groups or set(k.groups) & set(groups)):
                return k
        raise KeyError(f"{self.toml} has no key '{name}'")

    def allowed(self, groups: tuple[str, ...] = ()) -> tuple[str, ...]:
        """The keys an entry of the variant ``groups`` may hold, in table order."""
        return tuple(dict.fromkeys(k.name for k in self.keys
                                   if not k.groups or set(k.groups) & set(groups)))


METHODS = ("penalty", "film", "dme")
QUANTITIES = ("sigma_rr", "sigma_zz", "sigma_tt", "sigma_rz", "von_mises", "u_r", "u_z",
              "eps_p_eq", "yielded", "r", "z", "strain_gauge", "section")
# their names in a plane-strain scene (impact_fenics.geometry: the same slots)
PLANE_QUANTITIES = ("sigma_xx", "sigma_yy", "sigma_out", "sigma_xy", "von_mises", "u_x", "u_y",
                    "eps_p_eq", "yielded", "x", "y", "strain_gauge", "section")
GEOMETRIES = ("axisymmetric", "plane_strain")
MODELS = tuple(MATERIAL_MODELS)  # the materials by name (impact_fenics.materials.MODELS)
STRAIN_WORDS = {"small": "small strain", "finite": "finite strain"}
PULSES = {"trapezoid": ("peak", "t_rise", "t_fall", "t_end"), "constant": ("value", "t_end")}
WALL_METHODS = ("film", "dme", "penalty")
WALL_FACES = ("contact", "held")
DT_INTERVAL = 10  # finite strain: steps between re-estimates of the stable step (default)
ENERGY_EVERY = 10  # small strain: steps between energy rows (default)

# the mesh generators of the scene files: impact_fenics.meshing, and quad_bar and
# rod_on_anvil (impact_fenics.quad_meshes: quadrilaterals, finite-strain bodies or
# small-strain Q1 ones)
GENERATORS = ("bar", "coaxial_bars", "punch_block", "coaxial_bars_sized", "quad_bar",
              "rod_on_anvil", "nosed_striker_on_block", "shpb", "block", "wedge_on_block",
              "cylinder_on_block", "striker_on_plate")
QUAD_GENERATORS = ("quad_bar", "rod_on_anvil")  # impact_fenics.quad_meshes (not meshing)
# parameters a generator has no default for (impact_fenics.quad_meshes)
REQUIRED_PARAMS = {"quad_bar": ("radius", "length", "n_r"),
                   "rod_on_anvil": ("radius", "length", "n_r")}
_BARS = ("bar", "coaxial_bars", "coaxial_bars_sized", "quad_bar", "rod_on_anvil")
_TWO_BARS = ("coaxial_bars", "coaxial_bars_sized")
_GEN = "the generator's"

_MESH = Section("mesh", "[mesh]", (
    "The mesh: a generator of the package with its parameters, or a `.msh` file of "
    "your own. Every cell group of the mesh is a body ([bodies.NAME]); contact, loads "
    "and fixed faces name its facet groups. The generators, their groups and their "
    "defaults are listed below the table."), (
    Key("generator", "text", "", REQUIRED, "a mesh generator (or give `file`)",
        choices=GENERATORS, default_text="required, or `file`"),
    Key("file", "text", "", None, "instead of `generator`: a 2D `.msh` file (r = x, z = y) "
        "with named physical groups, relative to the scene file", default_text="none"),
    Key("radius", "positive", "m", _GEN, "radius of the bar (both bars)", groups=_BARS),
    Key("length", "positive", "m", _GEN, "length of the bar (the rod)",
        groups=("bar", "quad_bar", "rod_on_anvil")),
    Key("striker_length", "positive", "m", _GEN, "striker length (z in [-striker_length, 0])",
        groups=_TWO_BARS + ("shpb",)),
    Key("target_length", "positive", "m", _GEN, "target length (z in [0, target_length])",
        groups=_TWO_BARS),
    Key("h", "positive", "m", _GEN, "element size", groups=("bar", "coaxial_bars", "block")),
    Key("h_striker", "positive", "m", _GEN, "element size of the striker",
        groups=("coaxial_bars_sized", "nosed_striker_on_block")),
    Key("h_target", "positive", "m", _GEN, "element size of the target",
        groups=("coaxial_bars_sized",)),
    Key("structured", "flag", "", _GEN, "a structured grid of alternating diagonals",
        groups=("bar", "coaxial_bars", "coaxial_bars_sized", "shpb")),
    Key("width", "positive", "m", _GEN, "block radius", groups=("punch_block",)),
    Key("width", "positive", "m", _GEN, "block width (x in [0, width]; a plane-strain section, "
        "or r in axisymmetry)", groups=("block",)),
    Key("height", "positive", "m", _GEN, "block height (y in [0, height])", groups=("block",)),
    Key("quadrilaterals", "flag", "", _GEN, "Q1 quadrilaterals instead of triangles (with "
        "structured; a finite-strain body needs them)",
        groups=("block", "coaxial_bars_sized", "shpb")),
    Key("depth", "positive", "m", _GEN, "block depth (z in [-depth, 0])", groups=("punch_block",)),
    Key("h_surface", "positive", "m", _GEN, "element size at the surface", groups=("punch_block",)),
    Key("grading", "positive", "m/m", _GEN, "growth of the element size with the distance "
        "from the surface", groups=("punch_block",)),
    Key("h_max", "positive", "m", _GEN, "largest element size", groups=("punch_block",)),
    Key("breaks", "breaks", "m, -", _GEN, "surface breaks [[r, intervals], ...]: equal "
        "intervals up to each radius r", groups=("punch_block",)),
    Key("n_r", "count", "-", _GEN, "quadrilaterals across the radius (square cells, "
        "round(n_r length / radius) along)", groups=("quad_bar", "rod_on_anvil")),
    Key("anvil_radius", "positive", "m", None, "rod_on_anvil: the anvil's radius (r <= "
        "anvil_radius), at least the rod's", groups=("rod_on_anvil",),
        default_text="3 radius"),
    Key("anvil_depth", "positive", "m", None, "rod_on_anvil: the anvil's depth (z in "
        "[-anvil_depth, 0]; square cells of the rod's radial size)", groups=("rod_on_anvil",),
        default_text="2 radius"),
    Key("nose_radius", "positive", "m", _GEN, "striker and nose radius",
        groups=("nosed_striker_on_block",)),
    Key("shank_length", "positive", "m", _GEN, "striker length above the nose",
        groups=("nosed_striker_on_block",)),
    Key("block_width", "positive", "m", _GEN, "block radius", groups=("nosed_striker_on_block",)),
    Key("block_depth", "positive", "m", _GEN, "block depth",
        groups=("nosed_striker_on_block", "wedge_on_block")),
    Key("h_block", "positive", "m", _GEN, "element size of the block",
        groups=("nosed_striker_on_block", "wedge_on_block")),
    Key("wedge_angle", "positive", "deg", _GEN, "the wedge's included angle, below 180",
        groups=("wedge_on_block",)),
    Key("tip_radius", "positive", "m", _GEN, "radius of the wedge's round tip",
        groups=("wedge_on_block",)),
    Key("wedge_height", "positive", "m", _GEN, "height of the wedge above its tip (y = 0)",
        groups=("wedge_on_block",)),
    Key("block_width", "positive", "m", _GEN, "the block's half width (x in [0, block_width])",
        groups=("wedge_on_block",)),
    Key("h_wedge", "positive", "m", _GEN, "element size of the wedge",
        groups=("wedge_on_block",)),
    Key("radius", "positive", "m", _GEN, "the cylinder's radius R", groups=("cylinder_on_block",)),
    Key("gap", "number", "m", _GEN, "height of the cylinder's lowest line above the "
        "block's top (y = 0)", groups=("cylinder_on_block",)),
    Key("block_width", "positive", "m", _GEN, "the block's half width (x in [0, block_width]), "
        "beyond R sin(contact_angle)", groups=("cylinder_on_block",)),
    Key("block_depth", "positive", "m", _GEN, "the block's depth (y in [-block_depth, 0])",
        groups=("cylinder_on_block",)),
    Key("h_contact", "positive", "m", _GEN, "element size within contact_zone of the contact "
        "point, both bodies", groups=("cylinder_on_block",)),
    Key("h_far", "positive", "m", _GEN, "element size far from it (h_contact <= h_far < R)",
        groups=("cylinder_on_block",)),
    Key("contact_zone", "positive", "m", _GEN, "distance from the contact point meshed at "
        "h_contact (then growing to h_far over 20 h_far)", groups=("cylinder_on_block",)),
    Key("contact_angle", "positive", "deg", _GEN, "the arc of the group cylinder_contact, from "
        "the lowest line, below 90", groups=("cylinder_on_block",)),
    Key("quarter", "flag", "", _GEN, "only the quarter below the diametral plane (its face "
        "cylinder_top, to load it)", groups=("cylinder_on_block",)),
    Key("block", "flag", "", _GEN, "the block under the cylinder (false: the cylinder alone, "
        "on the [wall] say)", groups=("cylinder_on_block",)),
    Key("striker_half_width", "positive", "m", _GEN, "the striker's half width (x in [0, "
        "striker_half_width])", groups=("striker_on_plate",)),
    Key("striker_length", "positive", "m", _GEN, "the striker's length (y in [gap, gap + "
        "striker_length])", groups=("striker_on_plate",)),
    Key("gap", "number", "m", _GEN, "height of the striker's face above the plate's top "
        "(y = 0), >= 0", groups=("striker_on_plate",)),
    Key("plate_half_span", "positive", "m", _GEN, "the plate's half span (x in [0, "
        "plate_half_span]), beyond the striker's half width", groups=("striker_on_plate",)),
    Key("plate_thickness", "positive", "m", _GEN, "the plate's thickness (y in "
        "[-plate_thickness, 0])", groups=("striker_on_plate",)),
    Key("h_striker", "positive", "m", _GEN, "element size of the striker",
        groups=("striker_on_plate",)),
    Key("h_plate", "positive", "m", _GEN, "element size of the plate",
        groups=("striker_on_plate",)),
    Key("bar_diameter", "positive", "m", _GEN, "shpb: diameter of the striker and the bars",
        groups=("shpb",)),
    Key("incident_length", "positive", "m", _GEN, "shpb: incident bar length (z in [0, "
        "incident_length])", groups=("shpb",)),
    Key("transmitter_length", "positive", "m", _GEN, "shpb: transmitter bar length",
        groups=("shpb",)),
    Key("specimen_diameter", "positive", "m", _GEN, "shpb: specimen diameter (at most the "
        "bars')", groups=("shpb",)),
    Key("specimen_length", "positive", "m", _GEN, "shpb: specimen length", groups=("shpb",)),
    Key("h_bar", "positive", "m", _GEN, "shpb: element size of the striker and the bars",
        groups=("shpb",)),
    Key("h_specimen", "positive", "m", _GEN, "shpb: element size of the specimen",
        groups=("shpb",)),
    Key("bar_yield_stress", "positive", "Pa", None, "shpb: the bars' yield stress: a warning "
        "when the incident stress rho c0 v / 2 exceeds 0.8 of it (BAR_YIELD_FRACTION, impact_fenics/shpb/run_analysis.py)",
        groups=("shpb",), default_text="no check"),
), variants="`generator` chooses the parameters the table may hold; `file` takes none.")

def _kinematics_text(model: str) -> str:
    """'small strain', 'finite strain' or 'small and finite strain'."""
    return " and ".join(w.split()[0] for w in (STRAIN_WORDS[k] for k in MATERIAL_MODELS[model])) \
        + " strain"


def _material_keys() -> tuple[Key, ...]:
    """The keys of each model: its classes' parameters (names, units, ranges, meanings and
    scene defaults stated once, by the class), a key of one kinematics only marked so."""
    keys = []
    for model, classes in MATERIAL_MODELS.items():
        seen: set[str] = set()
        for cls in classes.values():
            for p in cls.parameters:
                if p.name in seen:
                    continue
                seen.add(p.name)
                only = [k for k, c in classes.items() if p.name in (q.name for q in c.parameters)]
                note = (f" ({STRAIN_WORDS[only[0]]} only)" if len(only) < len(classes) else "")
                default = REQUIRED if p.scene_default == REQUIRED else (
                    None if p.scene_default == CLASS_DEFAULT else p.scene_default)
                text = (f"required ({model})" if default == REQUIRED
                        else p.default_text if p.scene_default == CLASS_DEFAULT else "")
                rng = f", {p.range_text}" if p.range_text and not p.choices else ""
                keys.append(Key(p.name, "text" if p.choices else "number", p.unit, default,
                                f"{model}: {p.what}{rng}{note}", choices=p.choices,
                                groups=(model,), default_text=text))
    return tuple(keys)


_MATERIALS = Section("materials", "[materials.NAME]", (
    "A material, named for the bodies that use it: a model of the package by name, with "
    "its parameters as keys, or a class of your own by its import path "
    "([materials.md](materials.md)). A model serves the kinematics it has (`strain` of "
    "[bodies.NAME]): " + "; ".join(f"`{m}` {_kinematics_text(m)}" for m in MATERIAL_MODELS)
    + ". A body of a kinematics its model lacks is refused in one line."), (
    Key("model", "text", "", "elastic", "the constitutive model: a name, or "
        "\"package.module:Class\"", choices=MODELS,
        note="Linear elastic (at finite strain use neo_hookean); J2 (von Mises, linear "
        "isotropic hardening, radial return; at finite strain the multiplicative Hencky J2, "
        "rate-independent); Johnson-Cook (finite strain: hardening, rate and thermal "
        "softening, adiabatic heating); Drucker-Prager (small strain: rock, tension "
        "cut-off, non-associated flow); neo-Hookean (finite strain). A class of your own: "
        "its module is imported (also from the scene file's directory), every key of the "
        "table but `model` goes to its constructor as a keyword, and its `strain` "
        "attribute (\"small\" or \"finite\") is its kinematics."),
    Key("E", "positive", "Pa", REQUIRED, "Young's modulus"),
    Key("nu", "number", "-", REQUIRED, "Poisson's ratio, in (-1, 0.5)"),
    Key("density", "positive", "kg/m^3", REQUIRED, "mass density"),
) + _material_keys(), variants="`model` chooses the keys: `E`, `nu` and `density` for every "
    "material, then those of its model (marked `model:` below); a key of another model is "
    "refused. The parameters of each model are those of its class in "
    "`impact_fenics/materials/` (same names, units and ranges).")

_BODIES = Section("bodies", "[bodies.NAME]", (
    "A deformable body: one per cell group NAME of the mesh, and every cell group "
    "must be one."), (
    Key("material", "text", "", REQUIRED, "the name of a [materials.NAME] table"),
    Key("velocity", "pair", "m/s", [0.0, 0.0], "initial velocity [v_r, v_z] ([v_x, v_y] in "
        "plane strain)"),
    Key("strain", "text", "", "small", "the kinematics", choices=("small", "finite"),
        note="Small strain: the linear and small-strain plastic paths on triangles, or Q1 "
        "quadrilaterals with mean dilatation on `quad_bar` (one body, below). Finite "
        "strain: total Lagrangian, Q1 quadrilaterals with mean dilatation, a variable step "
        "(below)."),
))

_RIGID = Section("rigid", "[rigid.NAME]", (
    "A rigid body with one z degree of freedom (a punch, a drill bit; in plane strain y "
    "and a sideways x, its mass, forces and impedance those of the slab t), in exactly one "
    "[[contact]] or one [[tie]]."), (
    Key("mass", "positive", "kg", None, "mass", default_text="required (without "
        "prescribed_velocity)"),
    Key("velocity", "number", "m/s", 0.0, "initial z velocity"),
    Key("prescribed_velocity", "velocity_table", "m/s", None, "a prescribed z velocity (in "
        "plane strain y): a constant, or a table [[t, v], ...] (s, m/s) linear between its "
        "points and held after the last", default_text="none (the body moves by its mass "
        "and forces)", note="The body has no mass (infinite: the contact serves it as a "
        "fixed part that moves), each step moves it by the exact integral of v(t) over "
        "the step; mass, velocity, velocity_x, impedance and [[loads]] on it are refused. "
        "The history gets its u, v and reaction (N), the energy ledger the work of the "
        "motion. [friction.md](friction.md) section 12."),
    Key("velocity_x", "number", "m/s", 0.0, "plane strain: initial sideways (x) velocity",
        note="The body translates along x too (no rotation: an oblique face keeps its "
        "orientation); film, dme and penalty friction couple it to the face's nodes; "
        "refused in an axisymmetric scene (the axis). "
        "[friction.md](friction.md) section 11."),
    Key("impedance", "positive", "kg/s", None, "impedance Z = rho c A of a rod driving the body "
        "from above", default_text="none", note="The rod pushes with 2 F_i - Z w (w the "
        "downward velocity, F_i its incident wave: [[loads]] incident)."),
))

# Coulomb friction of a [[contact]] and of the [wall] (docs/friction.md)
_FRICTION = Key("friction", "friction", "-", 0.0, "Coulomb friction: a coefficient mu >= 0, \"stick\" (no "
        "slip at all) or {static, dynamic, decay} (mu = dynamic + (static - dynamic) "
        "exp(-decay |w_t|), decay in s/m, w_t the previous step's slip speed)", default_text="0 "
        "(frictionless)", note="Built for film, dme and penalty on node pairs, a rigid face (not a button), "
        "a small-strain wall and node to segment (film and dme on a curved master by the "
        "Tresca iteration, with e = 0; all three re-paired by repair_every, the penalty's "
        "spring carried with its segment), for all three on a finite-strain wall (the "
        "penalty's spring keeping its force at each change of step); refused in one line "
        "elsewhere (the penalty's "
        "friction on a curved master or re-paired with a normal bound past 1). "
        "[friction.md](friction.md).")
_TANGENTIAL_PENALTY = Key("tangential_penalty", "stiffness", "N/m", "scaled", "penalty with "
                          "friction: the tangential spring k_t", choices=("scaled",),
                          note="\"scaled\": beta_t = k_t h^2 (1/m_lo + 1/m_up) = 1 per row "
                          "(the penalty's stick is FILM's; node to segment: Gershgorin's "
                          "bound of h^2 K^1/2 T M^-1 T' K^1/2 is 1); a stiffness whose beta_t "
                          "passes 4/3 is refused unless forced.")

_CONTACT = Section("contact", "[[contact]]", (
    "A contact between two facet groups, or between a facet group and a rigid body, "
    "enforced by one method ([contact.md](contact.md)). A facet group may be in one "
    "[[contact]] only."), (
    Key("lower", "text", "", REQUIRED, "node pairs: the facet group of the body below",
        groups=("pairs",)),
    Key("upper", "text", "", REQUIRED, "node pairs: the facet group of the body above (its "
        "nodes pair with the lower ones by radius; by x in plane strain)", groups=("pairs",)),
    Key("surface", "text", "", REQUIRED, "rigid face: the facet group under the rigid body",
        groups=("rigid",)),
    Key("rigid", "text", "", REQUIRED, "rigid face: the name of a [rigid.NAME] body",
        groups=("rigid",)),
    Key("radius", "positive", "m", None, "rigid face: the radius of its flat face (r <= radius)",
        groups=("rigid",), default_text="required (axisymmetric)"),
    Key("half_width", "positive", "m", None, "rigid face in plane strain: the half-width b of "
        "its flat face (|x| <= b)", groups=("rigid",),
        default_text="required (plane strain)"),
    Key("button", "positive", "m", None, "rigid face: a spherical button (in plane strain a "
        "cylinder) of this radius R_s >= radius (half_width) instead of the flat face "
        "(initial gaps R_s - sqrt(R_s^2 - r^2), x for r in plane strain)",
        groups=("rigid",), default_text="flat face"),
    Key("slave", "text", "", REQUIRED, "node to segment: the facet group of the slave nodes "
        "(the finer face)", groups=("segment",)),
    Key("master", "text", "", REQUIRED, "node to segment: the facet group of the master "
        "segments", groups=("segment",)),
    Key("reach", "positive", "m", None, "node to segment: the farthest master segment a slave "
        "may use", groups=("segment",), default_text="the longest master segment plus the "
        "faces' depth", note="The depth: the larger of the master's extent along the slave "
        "face's normal and the slave's along the master's. A flat face on a flat face keeps "
        "one segment; the nodes under a nose of radius R are within R of it."),
    Key("repair_every", "count", "-", 0, "node to segment: steps between re-pairings of the "
        "slaves with the segments they face, in the current configuration (the set-up's "
        "pairs for the whole run when absent)", groups=("segment",), default_text="never",
        note="For faces that slide along each other by more than a fraction of a segment. "
        "Each re-pairing searches within two of the longest master segments; a slave past "
        "an end of the master face by more than 1 % of the end segment has no row until "
        "it comes back ([node_to_segment.md](node_to_segment.md)). Needs film_solver = "
        "\"fast\"."),
    Key("method", "text", "", REQUIRED, "the contact method", choices=METHODS),
    Key("penalty", "stiffness", "N/m", "scaled", "penalty: a stiffness p", choices=("auto", "scaled"),
        note="\"auto\": the paper's rule (both readings reported); \"scaled\": from the "
        "coupled operator, beta_max = 1. A stiffness whose beta_max exceeds 4/3 is refused "
        "unless forced."),
    Key("restitution", "number", "-", 0.0, "dme: restitution e in [0, 1], per node pair at each "
        "activation", note="It is not the bodies' coefficient of restitution: on elastic bodies "
        "the waves bring nodes back into contact and each re-activation bounces again, so a "
        "Hertz impact with e > 0 shows 2 to 4 separations ([contact.md](contact.md#the-"
        "parameters))."),
    Key("positions", "text", "", "mass_weighted", "dme: the positions of a merged pair: "
        "mass-weighted, or the paper's equal weights (its eq. 9)",
        choices=("mass_weighted", "paper")),
    Key("film_solver", "text", "", "fast", "film: the exact O(n log n) solver, or the dense "
        "factorisation the paper timed", choices=("fast", "dense")),
    _FRICTION,
    _TANGENTIAL_PENALTY,
), variants="`rigid` makes a rigid face, `slave`/`master` node to segment, else `lower`/"
            "`upper` node pairs. `penalty`, `restitution`, `positions` and `film_solver` are "
            "read by their method only (a warning names a key the method ignores).")

_TIE = Section("tie", "[[tie]]", (
    "A facet group bonded to a rigid body (a button brazed on a bit, a platen bonded to a "
    "specimen): every node of the face moves with the body at every step, in tension as "
    "in compression, its u_r (u_x in plane strain) held at 0 and its initial velocity the "
    "body's ([one_loop.md](one_loop.md#a-tie)). The body is in this [[tie]] only (no "
    "[[contact]] besides); the face is in no [[contact]]. No friction keys (a bonded face "
    "does not slide) and no method: the tie is DME's cluster without release."), (
    Key("surface", "text", "", REQUIRED, "the facet group tied under the rigid body"),
    Key("rigid", "text", "", REQUIRED, "the name of a [rigid.NAME] body (free, with a rod, "
        "prescribed or fixed)"),
    Key("radius", "positive", "m", None, "the tied nodes: those of `surface` with r <= radius "
        "(as a rigid [[contact]] selects its face)", default_text="required (axisymmetric)"),
    Key("half_width", "positive", "m", None, "plane strain: the tied nodes are those with "
        "|x| <= half_width", default_text="required (plane strain)"),
))

_LOADS = Section("loads", "[[loads]]", (
    "A time-dependent load: a pressure or traction on a facet group, or a z force on "
    "a rigid body. The pulse (its time function) multiplies it."), (
    Key("facet", "text", "", REQUIRED, "a facet group under a pressure (Pa, pushing into the "
        "body)", groups=("facet",)),
    Key("traction", "pair", "Pa", None, "instead of a pressure: the traction [t_r, t_z] ([t_x, "
        "t_y] in plane strain) per unit of the pulse", groups=("facet",),
        default_text="a pressure"),
    Key("rigid", "text", "", REQUIRED, "a [rigid.NAME] body pushed by a z force (N)",
        groups=("rigid",)),
    Key("area", "positive", "m^2", None, "the pulse is a pressure (Pa) on this area pushing the "
        "rigid body down: force = -area x pulse", groups=("rigid",), default_text="a force"),
    Key("incident", "flag", "", False, "the pulse is the incident compressive force wave F_i "
        "(N) in the rod of a rigid body with `impedance`; the summary gets the incident, "
        "reflected and delivered wave energies", groups=("rigid",)),
    Key("pulse", "text", "", "trapezoid", "the time function", choices=tuple(PULSES)),
    Key("peak", "number", "Pa or N", REQUIRED, "trapezoid: the plateau value",
        groups=("trapezoid",)),
    Key("t_rise", "number", "s", REQUIRED, "trapezoid: end of the linear rise from 0, >= 0",
        groups=("trapezoid",)),
    Key("t_fall", "number", "s", REQUIRED, "trapezoid: start of the linear fall, >= t_rise",
        groups=("trapezoid",)),
    Key("t_end", "number", "s", REQUIRED, "trapezoid: end of the pulse (0 after), >= t_fall",
        groups=("trapezoid",)),
    Key("value", "number", "Pa or N", REQUIRED, "constant: the load", groups=("constant",)),
    Key("t_end", "positive", "s", None, "constant: the load is `value` for 0 <= t < t_end "
        "and 0 from t_end on", groups=("constant",), default_text="never (held)"),
), variants="`rigid` makes a load on a rigid body, else on `facet`; `pulse` chooses the "
            "pulse's keys.")

_FIXED = Section("fixed", "[[fixed]]", (
    "Displacement components held at zero on a facet group (u_r = 0 on the axis is "
    "automatic; in plane strain u_x = 0 on x = 0 with `symmetry = \"x=0\"`)."), (
    Key("facet", "text", "", REQUIRED, "the facet group held"),
    Key("components", "list", "", REQUIRED, "the components held: [\"r\"], [\"z\"] or "
        "[\"r\", \"z\"] (plane strain: \"x\", \"y\")", choices=("r", "z", "x", "y")),
))

_TIME = Section("time", "[time]", (
    "The step and the duration: exactly one of `dt` and `cfl`, and one of `t_end` and "
    "`n_steps`."), (
    Key("dt", "positive", "s", None, "the time step", default_text="one of dt, cfl"),
    Key("cfl", "positive", "-", None, "the step as a fraction of the stable limit (element "
        "bound; finite strain: <= 1 of the current cells' limit, re-estimated)",
        default_text="one of dt, cfl"),
    Key("t_end", "positive", "s", None, "the end time", default_text="one of t_end, n_steps"),
    Key("n_steps", "count", "-", None, "the number of steps (small strain)",
        default_text="one of t_end, n_steps"),
    Key("force_dt", "flag", "", False, "run although dt is above the stable limit (small strain)"),
    Key("converged_dt", "flag", "", False, "also compute the converged stable dt 2 / omega_max "
        "(SLEPc) into the summary (small strain)"),
    Key("dt_interval", "count", "-", None, "finite strain: steps between re-estimates of the "
        "stable step", default_text=str(DT_INTERVAL)),
))

_OUTPUT = Section("output", "[output]", (
    "What a run writes and where ([outputs.md](outputs.md))."), (
    Key("dir", "text", "", None, "the output directory, relative to the working directory "
        "(`--out` replaces it)", default_text="results/<scene file name>"),
    Key("output_every", "count", "-", 50, "steps between field outputs (fields.xdmf)"),
    Key("energy_every", "count", "-", None, "steps between energy rows (energy.csv) and their "
        "check of the energy's growth", default_text=str(ENERGY_EVERY)),
    Key("history_every", "count", "-", 1, "steps between history.csv rows"),
    Key("pairs_every", "count", "-", 10, "steps between the per-pair rows of contact_pairs.h5 "
        "(24 B a pair each)"),
    Key("fields", "flag", "", True, "write fields.xdmf"),
    Key("plots", "flag", "", True, "write history.png and energy.png"),
))

_PROBES = Section("probes", "[[probes]]", (
    "A history column: a quantity in the cell that holds a point (not on the interface "
    "of two bodies), the current position of a node near it, the axial strain a "
    "strain gauge centred at the point reads (both ends in one body), or the axial force "
    "through a plane of a linear body's nodes (a section)."), (
    Key("name", "text", "", None, "the column's name (unique; not step, time or dt)",
        default_text="<quantity>_<k>"),
    Key("point", "pair", "m", None, "the point [r, z], r >= 0 ([x, y] in plane strain)",
        default_text="required (a strain_gauge: or z; a section: z)"),
    Key("z", "number", "m", None, "a strain_gauge on the surface: its centre's height, at r = "
        "the mesh's outer radius there (the largest r of a cell at that z), instead of point; "
        "a section: the height of its plane (required)"),
    Key("quantity", "text", "", REQUIRED, "stresses in Pa, displacements in m; eps_p_eq and "
        "yielded with a j2 body; r and z (m): the current position X + u of the node "
        "nearest the point, among the nodes of the body whose cell holds it; strain_gauge (-): "
        "the axial strain (u_z(r, z + l/2) - u_z(r, z - l/2)) / l over the gauge length l "
        "centred at the point, compression negative; section (N): the axial force through "
        "the plane z, compression positive",
        choices=QUANTITIES + PLANE_QUANTITIES[:4] + PLANE_QUANTITIES[5:7]
        + PLANE_QUANTITIES[9:11],
        note="A gauge bonded on a bar's surface has r = the bar's radius; u_z is interpolated "
        "at each end (linear on a triangle, bilinear on a quadrilateral), so a linear field "
        "reads exactly. Both ends must lie in one body. A section's plane is a row of nodes "
        "of one linear elastic body with cells of it on both sides; its force is the z "
        "force the cells below exert on the plane's nodes (LS-DYNA's cross-section), whose "
        "impulse with the other forces on the nodes at and above the plane is their change "
        "of momentum."),
    Key("length", "positive", "m", 0.002, "the gauge length l of a strain_gauge (no other "
        "quantity takes it)"),
))

_WALL = Section("wall", "[wall]", (
    "A fixed rigid plane z = const (normal +z; in plane strain y = z, normal +y) at or "
    "below the body: every "
    "boundary node a unilateral candidate (a side node that folds onto it joins as it "
    "reaches it); its contact columns are named boundary/wall."), (
    Key("z", "number", "m", 0.0, "height of the plane"),
    Key("method", "text", "", REQUIRED, "the wall's contact method", choices=WALL_METHODS),
    Key("penalty", "stiffness", "N/m", "scaled", "penalty: a stiffness p", choices=("scaled",),
        note="beta = p dt^2 / m <= 4/3 at the lightest node, else refused unless forced; "
        "\"scaled\": beta = 1 at every step (FILM's correction as a spring)."),
    Key("face", "text", "", "contact", "the impact face", choices=WALL_FACES,
        note="contact: unilateral (its rim may lift off); held: u_z = 0 on Z = 0 from t = 0, "
        "sliding radially (the Taylor references' condition; needs z = 0; finite strain "
        "only: a small-strain face is held by [[fixed]])."),
    _FRICTION,
    _TANGENTIAL_PENALTY,
))

_TABLES = (_MESH, _MATERIALS, _BODIES, _RIGID, _CONTACT, _TIE, _LOADS, _FIXED, _TIME, _OUTPUT,
           _PROBES, _WALL)

TOP = Section("top", "top level", "Keys outside every table.", (
    Key("title", "text", "", None, "a name for the run's report", default_text="the file name"),
    Key("geometry", "text", "", "axisymmetric", "the section's geometry: a body of revolution "
        "(r, z), or plane strain (x, y) of a slab of thickness `thickness`",
        choices=GEOMETRIES, note="Plane strain: every mass (kg), force (N), energy (J) and "
        "slab-scaled input is that of the slab t; the stresses are named sigma_xx, sigma_yy, "
        "sigma_out (out of the plane, eps_out = 0), sigma_xy, the displacements u_x, u_y, "
        "and nothing is held on x = 0 unless `symmetry` says so. It runs small-strain "
        "bodies, linear elastic and path-dependent (J2, Drucker-Prager: the plastic "
        "strain's out-of-plane component evolves) and finite-strain bodies (Q1 F-bar, "
        "every finite-strain material), with contact (node pairs paired by x, node to "
        "segment, a rigid face of a `half_width` moving along y, the wall) and its "
        "friction (along x) ([plane_strain.md](plane_strain.md))."),
    Key("thickness", "positive", "m", None, "plane strain: the slab's thickness t",
        default_text="1 (per metre)"),
    Key("symmetry", "text", "", None, "plane strain: a symmetry plane of a half model, u_x = 0 "
        "on the nodes of x = 0", choices=("x=0",), default_text="none"),
    Key("force", "flag", "", False, "run what the checks refuse: dt above the stable limit, a "
        "penalty above its stable bound, a run estimated beyond the memory or the free disk"),
) + tuple(Key(s.name, "array" if s.toml.startswith("[[") else
              "tables" if ".NAME" in s.toml else "table", "",
              REQUIRED if s.name in ("mesh", "time") else None, s.toml)
          for s in _TABLES))

SECTIONS: dict[str, Section] = {"top": TOP, **{s.name: s for s in _TABLES}}
