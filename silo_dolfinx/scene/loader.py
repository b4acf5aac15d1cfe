"""Read, override, validate and resolve scene files.

``load_scene(path, overrides)`` returns a :class:`Scene` in which every key has a value
(defaults and derived values filled in) or raises :class:`SceneError` listing every problem,
each naming the key, the value, what is allowed and how to fix it. Nothing is meshed or
allocated before this succeeds.
"""

from __future__ import annotations

import difflib
import math
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

import tomli_w

from silo_dolfinx.scene.errors import Problem, SceneError
from silo_dolfinx.scene.schema import (
    DERIVED,
    REQUIRED,
    REQUIRED_SECTIONS,
    SECTION_BY_NAME,
    SECTIONS,
    TOP_KEYS,
    Key,
    Section,
)


class SceneSection(Mapping):
    """Read-only view of one resolved section with attribute access (``scene.material.density``)."""

    def __init__(self, name: str, data: dict[str, Any]):
        object.__setattr__(self, "_name", name)
        object.__setattr__(self, "_data", dict(data))

    def __getattr__(self, key: str) -> Any:
        try:
            return self._data[key]
        except KeyError:
            raise AttributeError(f"[{self._name}] has no key {key!r}") from None

    def __setattr__(self, key, value):
        raise AttributeError("scene sections are read-only; use --set or edit the scene file")

    def __getitem__(self, key: str) -> Any:
        return self._data[key]

    def __iter__(self):
        return iter(self._data)

    def __len__(self) -> int:
        return len(self._data)

    def __repr__(self) -> str:
        return f"SceneSection({self._name}, {self._data})"


class Scene:
    """A validated, fully resolved scene."""

    def __init__(self, data: dict[str, Any], source: Path | None, warnings: list[str]):
        self._data = data
        self.source = source
        self.warnings = warnings
        self.title: str = data["title"]
        self.description: str = data["description"]
        for s in SECTIONS:
            setattr(self, s.name, SceneSection(s.name, data[s.name]))
        self._outline = None

    @property
    def outline(self):
        """The silo geometry (analytic wall, outlet, fill) described by [geometry]."""
        if self._outline is None:
            from silo_dolfinx.geometry.shapes import outline_from_geometry

            self._outline = outline_from_geometry(self._data["geometry"])
        return self._outline

    @property
    def cone(self) -> dict[str, Any] | None:
        """The material's angles as given (φ, ψ: Mohr-Coulomb unless cone = "beta") and the
        Drucker-Prager slopes they map to (β, ψ_DP), in degrees; None for an elastic solid."""
        m = self.material
        if "friction_angle" not in m:
            return None
        from silo_dolfinx.theory import drucker_prager_cone, mohr_coulomb_angle

        cone = m.get("cone", "compression")  # mohr_coulomb: the cone through its compression corners
        beta, psi_dp = drucker_prager_cone(m.friction_angle, m.dilation_angle, cone)
        phi = m.friction_angle if cone != "beta" else mohr_coulomb_angle(beta, "compression")
        return {"cone": m.get("cone"), "friction_angle": m.friction_angle, "dilation_angle": m.dilation_angle,
                "beta": beta, "psi_dp": psi_dp, "phi_mohr_coulomb": phi}

    def cone_text(self) -> str:
        """One line: what the material's angles resolve to (for silo check, scene.toml, logs)."""
        c = self.cone
        if c is None:
            return "elastic solid: no friction angle"
        if c["cone"] is None:
            from silo_dolfinx.theory import drucker_prager_cone

            beta_e = drucker_prager_cone(c["friction_angle"], 0.0, "extension")[0]
            return (f"Mohr-Coulomb friction_angle φ = {c['friction_angle']:g}°, dilation_angle ψ = "
                    f"{c['dilation_angle']:g}° on Mohr-Coulomb's pyramid (model = \"mohr_coulomb\": no cone; "
                    f"the Drucker-Prager cones through its compression and extension corners have β = "
                    f"{c['beta']:.2f}° and {beta_e:.2f}°)")
        if c["cone"] == "beta":
            return (f"friction_angle {c['beta']:g}° and dilation_angle {c['psi_dp']:g}° are the Drucker-Prager "
                    f"slopes β, ψ (cone = \"beta\"); in axisymmetric compression β is Mohr-Coulomb φ = "
                    f"{c['phi_mohr_coulomb']:.2f}°")
        return (f"Mohr-Coulomb friction_angle φ = {c['friction_angle']:g}°, dilation_angle ψ = "
                f"{c['dilation_angle']:g}° -> Drucker-Prager β = {c['beta']:.2f}°, ψ_DP = {c['psi_dp']:.2f}° "
                f"(cone = \"{c['cone']}\")")

    def to_dict(self) -> dict[str, Any]:
        import copy

        return copy.deepcopy(self._data)

    def to_toml(self) -> str:
        """The resolved scene as TOML: loading it again gives the same scene."""
        d = self.to_dict()
        d.pop("base", None)
        lines = [f"# {self.cone_text()}"] + [f"{k} = {_toml_value(d[k])}" for k in ("title", "description")]
        for s in SECTIONS:
            lines += ["", f"[{s.name}]"] + [f"{k} = {_toml_value(v)}" for k, v in d[s.name].items()]
        return "\n".join(lines) + "\n"

    def with_overrides(self, overrides: list[str]) -> Scene:
        return load_scene(self.to_dict(), overrides, source=self.source)


def _toml_value(v) -> str:
    """One TOML value on one line (scene values are scalars, lists and lists of pairs)."""
    if isinstance(v, str):
        return tomli_w.dumps({"v": v})[4:].strip()
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, int):
        return str(v)
    return "[" + ", ".join(_toml_value(x) for x in v) + "]"


# ---------------------------------------------------------------------------- reading
def read_toml(path: Path, _seen: tuple[Path, ...] = ()) -> dict[str, Any]:
    """Read a scene file, following ``base = "other.toml"`` (relative to the file)."""
    path = Path(path).resolve()
    if path in _seen:
        chain = " -> ".join(p.name for p in _seen + (path,))
        raise SceneError(Problem("", "base", f"circular base chain {chain}. Fix: remove one base."))
    if not path.is_file():
        raise SceneError(Problem("", "base" if _seen else "scene",
                                 f"file {str(path)!r} not found. Fix: check the path."))
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as e:
        raise SceneError(Problem("", "syntax", f"{path.name}: {e}. Fix: correct the TOML syntax."),
                         str(path)) from None
    base = data.get("base", "")
    if base:
        if not isinstance(base, str):
            raise SceneError(Problem("", "base", f"= {base!r}: must be a file path string."))
        parent = read_toml(path.parent / base, _seen + (path,))
        parent.pop("title", None)
        parent.pop("description", None)
        data = _merge(parent, data)
    return data


def _merge(a: dict, b: dict) -> dict:
    out = dict(a)
    for k, v in b.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = _merge(out[k], v)
        else:
            out[k] = v
    return out


def apply_overrides(data: dict[str, Any], overrides: list[str] | tuple[str, ...]) -> dict[str, Any]:
    """Apply ``section.key=value`` overrides (value in TOML syntax; bare words are strings)."""
    data = _merge({}, data)
    for item in overrides or ():
        if "=" not in item:
            raise SceneError(Problem("", "--set", f"{item!r} is not of the form section.key=value. "
                                     "Fix: e.g. --set material.density=1500"))
        path, raw = item.split("=", 1)
        path = path.strip()
        try:
            value = tomllib.loads(f"v = {raw.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            value = raw.strip()
        parts = path.split(".")
        if len(parts) == 1:
            data[parts[0]] = value
        elif len(parts) == 2:
            sec = data.setdefault(parts[0], {})
            if not isinstance(sec, dict):
                raise SceneError(Problem(parts[0], parts[1], "cannot override: the section is not a table."))
            sec[parts[1]] = value
        else:
            raise SceneError(Problem("", "--set", f"{path!r}: use section.key (one dot). "
                                     "Fix: e.g. --set geometry.element_size=0.02"))
    return data


# ---------------------------------------------------------------------------- validation
def load_scene(
    scene: str | Path | Mapping[str, Any],
    overrides: list[str] | tuple[str, ...] = (),
    *,
    source: Path | None = None,
) -> Scene:
    """Load and validate a scene (a file path or a dict); raise :class:`SceneError` if unusable."""
    if isinstance(scene, str | Path):
        source = Path(scene)
        raw = read_toml(source)
    else:
        raw = _merge({}, dict(scene))
        if raw.get("base"):  # a dict may start from a file too (relative to source, else cwd)
            parent = read_toml((Path(source).parent if source else Path.cwd()) / raw["base"])
            parent.pop("title", None)
            parent.pop("description", None)
            raw = _merge(parent, raw)
    raw = apply_overrides(raw, overrides)
    problems: list[Problem] = []
    warnings: list[str] = []
    out: dict[str, Any] = {}

    # top-level keys and sections
    top_names = {k.name for k in TOP_KEYS}
    for name, value in raw.items():
        if name in top_names or name in SECTION_BY_NAME:
            continue
        if isinstance(value, dict):
            problems.append(Problem(name, "(section)", "unknown section." + _suggest(name, SECTION_BY_NAME)
                                    + f" Sections: {', '.join(SECTION_BY_NAME)}. Fix: rename it to one of these, or "
                                    "remove it."))
        else:
            problems.append(Problem("", name, "unknown top-level key." + _suggest(name, top_names | set(SECTION_BY_NAME))
                                    + f" Top-level keys: {', '.join(sorted(top_names))}; everything "
                                    "else belongs in a [section]. Fix: move it into its [section], or remove it."))
    for k in TOP_KEYS:
        v = raw.get(k.name, k.default)
        problems += _check_value("", k, v) if k.name in raw else []
        out[k.name] = v
    if not out["title"] and source is not None:
        out["title"] = Path(source).stem
    out["base"] = ""  # inheritance is resolved: the resolved scene stands alone

    for name in REQUIRED_SECTIONS:
        if name not in raw:
            problems.append(Problem(name, "(section)", f"missing section [{name}]. Fix: add it; see "
                                    "docs/scene.md for its keys."))
    for sec in SECTIONS:
        given = raw.get(sec.name, {})
        if not isinstance(given, dict):
            problems.append(Problem(sec.name, "(section)", f"must be a table, got {given!r}. Fix: "
                                    f"write [{sec.name}] followed by key = value lines."))
            given = {}
        resolved, probs, warns = _resolve_section(sec, given, present=sec.name in raw)
        out[sec.name] = resolved
        problems += probs
        warnings += warns
    if problems:
        raise SceneError(problems, str(source) if source else None)

    problems += _cross_checks(out)
    if problems:
        raise SceneError(problems, str(source) if source else None)
    # Geometry: shape consistency and derived sizes (pure Python, no meshing).
    from silo_dolfinx.geometry.shapes import resolve_geometry

    problems += resolve_geometry(out["geometry"])
    if not problems:
        problems += _resolve_derived(out)
    if not problems:
        problems += _feasibility(out)
    if problems:
        raise SceneError(problems, str(source) if source else None)
    d = out["discharge"]
    if d["mode"] == "controlled" and d["ramp_time"] > d["duration"]:
        warnings.append(f"[discharge] ramp_time = {d['ramp_time']:g} s is longer than the discharge (duration = "
                        f"{d['duration']:g} s): the outlet reaches only part of velocity = {d['velocity']:g} m/s.")
    scene = Scene(out, Path(source) if source else None, warnings)
    warnings += _flat_bottom_discharge_advice(out, scene.outline)  # (the scene's outline, built once and kept)
    warnings += _outlet_column_advice(out, scene.outline)
    return scene


def _flat_bottom_discharge_advice(s: dict, outline) -> list[str]:
    """Before any step: a free discharge of a flat-bottomed silo on a plastic law wants the apex
    opening closed again (material.recompaction) and a free surface that slumps at about φ
    (ale.max_surface_slope). Without the first, the cells over the outlet open without end and
    the flow decays (a user's sand silo: 174 -> 82 kg/s in 12 s, a cell at 1 % of its density);
    with it alone, the channel reaches the surface and a pit on the axis ends the run (3.9 s);
    with both, 203-216 kg/s for the 12 s (docs/guide/your-silo.md, section 5). The ch. 8 silo
    (outlet 0.125 of radius 0.35 m) decays without it and pipes to its surface with it. Said
    before the run so that it costs nothing to act on; the run is not refused."""
    m, d, a = s["material"], s["discharge"], s["ale"]
    if d["mode"] != "free" or d["duration"] <= 0.0 or "recompaction" not in m:
        return []
    if outline.floor_pieces == 0:  # any wall with a floor at the outlet
        return []
    fix = [k for k, off in (("material.recompaction = true", not m["recompaction"]),
                            (f"ale.max_surface_slope = {m['friction_angle']:g} (φ)",
                             a["enabled"] and a["max_surface_slope"] == 0.0)) if off]
    if not fix:
        return []
    return [f"[discharge] a flat-bottomed silo's free discharge without {' and '.join(fix)}: the cells "
            "over the outlet open and are never closed, and the flow decays (a sand silo 174 -> 82 kg/s in "
            "12 s; the ch. 8 silo 56 -> 28 kg/s in 4 s), or a pit on the axis ends the run. Set "
            + " and ".join(fix) + " (flat_bottom_ch6_discharge.toml does; the sand silo then held 203-216 "
            "kg/s); an outlet wide against the silo may then pipe to the surface and end on mesh quality "
            "(docs/guide/your-silo.md, section 5)."]


def _outlet_column_advice(s: dict, outline) -> list[str]:
    """Before any step: on a structured mesh with a floor the outlet's column of cells runs the
    silo's full height, so a refined outlet (outlet_size_factor) makes that column - and the
    columns graded beside it - needles from the refinement distance up, past max_aspect_ratio,
    which the mesher honours only without a floor. Measured on the ch. 6 silo (h 0.02 m, 10 s of
    free discharge, docs/validation/ch6.md): 8 cells across the outlet radius, 8× needles over
    58 % of the cells, 1.457 kg/s against 1.095 unstructured; 4 cells, 4×: 1.073 against 0.934."""
    g, d = s["geometry"], s["discharge"]
    if g["mesh"] != "structured" or g["mesh_file"] or not outline.has_floor or d["mode"] == "none":
        return []
    from silo_dolfinx.geometry.mesher import MeshOptions

    h, r0 = g["element_size"], outline.outlet_radius
    across = MeshOptions.from_geometry(g).outlet_column_cells(outline)
    aspect = h * across / r0  # the outlet column's cells where the rows are element_size tall
    if aspect <= g["max_aspect_ratio"] * (1.0 + 1e-9):
        return []
    return [f"[geometry] outlet_size_factor = {g['outlet_size_factor']:g} on a structured mesh with a floor: the "
            f"outlet's column of {across} cells runs the silo's height, so its cells and the columns graded beside "
            f"them are up to {aspect:.1f}× taller than wide above z = {g['refinement_distance']:g} m (max_aspect_ratio "
            f"= {g['max_aspect_ratio']:g} holds only without a floor). Such needles speed a discharge up: the ch. 6 "
            "silo at 8 cells across its outlet radius ran at 1.46 kg/s on them against 1.10 kg/s unstructured (4 "
            "cells: 1.07 against 0.93). Fix: geometry.mesh = \"unstructured\" (refines around the outlet only), "
            f"or element_size ≤ {g['max_aspect_ratio'] * r0 / across:.3g} m (docs/validation/ch6.md)."]


def load_geometry(geometry: Mapping[str, Any]) -> dict[str, Any]:
    """Validate and resolve a [geometry] section on its own (for gmsh scripts and tools)."""
    g, problems, _ = _resolve_section(SECTION_BY_NAME["geometry"], dict(geometry), present=True)
    if not problems:
        from silo_dolfinx.geometry.shapes import resolve_geometry

        problems = resolve_geometry(g)
    if problems:
        raise SceneError(problems)
    return g


def _resolve_section(sec: Section, given: dict, present: bool):
    problems: list[Problem] = []
    warnings: list[str] = []
    variant = None
    if sec.selector:
        skey = next(k for k in sec.keys if k.name == sec.selector)
        variant = given.get(sec.selector, skey.default)
        if variant is REQUIRED:
            if present or sec.name in REQUIRED_SECTIONS:
                problems.append(_missing(sec, skey, None))
            return {}, problems, warnings
        p = _check_value(sec.name, skey, variant)
        if p:
            return {}, p, warnings
    keys = sec.keys_for(variant)
    if sec.selector:  # selector first, then the variant's keys, then the common keys
        keys = keys[:1] + sec.variants.get(variant, ()) + sec.keys[1:]
    names = {k.name for k in keys}
    other = sec.all_key_names() - names
    resolved: dict[str, Any] = {}
    for name, value in given.items():
        if name in names:
            continue
        if name in other:
            warnings.append(f"[{sec.name}] {name} is ignored: it is not used when "
                            f"{sec.selector} = {variant!r}.")
            continue
        choices = sorted(names)
        problems.append(Problem(sec.name, name, "unknown key." + _suggest(name, names)
                                + f" Keys of [{sec.name}]"
                                + (f" ({sec.selector} = {variant!r})" if variant else "")
                                + f": {', '.join(choices)}. Fix: rename it to one of these, or remove it."))
    for k in keys:
        if k.name in given:
            p = _check_value(sec.name, k, given[k.name])
            problems += p
            if not p:
                resolved[k.name] = _normalise(k, given[k.name])
        elif k.default is REQUIRED:
            problems.append(_missing(sec, k, variant))
        else:
            resolved[k.name] = k.default if k.default is DERIVED else _normalise(k, k.default)
    return resolved, problems, warnings


def _missing(sec: Section, k: Key, variant) -> Problem:
    why = f" (required for {sec.selector} = {variant!r})" if variant else " (required)"
    unit = f" ({k.unit})" if k.unit and k.unit != "-" else ""
    return Problem(sec.name, k.name, f"missing{why}: {k.doc} Fix: add `{k.name} = "
                   f"{_fmt(k.example_value())}`{unit} to [{sec.name}].")


def _normalise(k: Key, v):
    if k.kind == "float":
        return float(v)
    if k.kind == "int":
        return int(v)
    if k.kind == "floats":
        return [float(x) for x in v]
    if k.kind in ("points", "locations"):
        return [[float(a), float(b)] for a, b in v]
    if k.kind == "strings":
        return [str(x) for x in v]
    return v


def _is_num(v) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


def _check_value(section: str, k: Key, v) -> list[Problem]:
    ex = _fmt(k.example_value())
    fix = f" Fix: e.g. `{k.name} = {ex}`."
    unit = f" {k.unit}" if k.unit and k.unit != "-" else ""
    want = {"float": "a number", "int": "an integer", "bool": "true or false", "str": "a string",
            "choice": "a string", "floats": "a list of numbers", "strings": "a list of strings",
            "points": "a list of [r, z] pairs",
            "locations": "a list of [r, z] pairs"}
    if k.kind == "float" and not _is_num(v) or k.kind == "bool" and not isinstance(v, bool) \
            or k.kind in ("str", "choice") and not isinstance(v, str):
        return [Problem(section, k.name, f"= {v!r}: wrong type, expected {want[k.kind]}{unit}.{fix}")]
    if k.kind == "int" and not (isinstance(v, int) and not isinstance(v, bool)
                                or isinstance(v, float) and v.is_integer()):
        return [Problem(section, k.name, f"= {v!r}: wrong type, expected an integer.{fix}")]
    if k.kind == "choice" and v not in k.choices:
        return [Problem(section, k.name, f"= {v!r} is not allowed: must be {k.range_text()}."
                        + (_suggest(v, k.choices) or fix))]
    if k.kind in ("float", "int"):
        if isinstance(v, float) and not math.isfinite(v):
            return [Problem(section, k.name, f"= {v!r}: must be finite, {k.range_text()}.{fix}")]
        if not _in_range(k, v):
            return [Problem(section, k.name, f"= {_fmt(v)} is out of range: must be {k.range_text()}.{fix}")]
    if k.kind == "floats":
        if not isinstance(v, list | tuple) or not all(_is_num(x) for x in v):
            return [Problem(section, k.name, f"= {v!r}: wrong type, expected a list of numbers.{fix}")]
        if k.length is not None and len(v) != k.length:
            return [Problem(section, k.name, f"= {v!r}: needs exactly {k.length} numbers.{fix}")]
        bad = [x for x in v if not math.isfinite(x) or not _in_range(k, x)]
        if bad:
            return [Problem(section, k.name, f"= {v!r}: every entry must be {k.range_text()} "
                            f"(offending: {_fmt(bad[0])}).{fix}")]
    if k.kind == "strings":
        if not isinstance(v, list | tuple) or not all(isinstance(x, str) and len(x) <= 24 for x in v):
            return [Problem(section, k.name, f"= {v!r}: wrong type, expected a list of short strings (at most 24 "
                            f"characters each, or []).{fix}")]
    if k.kind == "locations":
        ok = isinstance(v, list | tuple) and all(
            isinstance(p, list | tuple) and len(p) == 2 and all(_is_num(x) and math.isfinite(x) for x in p) for p in v)
        if not ok:
            return [Problem(section, k.name, f"= {v!r}: must be a list of [r, z] pairs of numbers (or []). "
                            f"Fix: e.g. `{k.name} = {ex}`.")]
    if k.kind == "points":
        ok = isinstance(v, list) and len(v) >= 2 and all(
            isinstance(p, list) and len(p) == 2 and all(_is_num(x) and math.isfinite(x) for x in p) for p in v)
        if not ok:
            return [Problem(section, k.name, "must be a list of at least two [r, z] pairs of numbers."
                            f" Fix: e.g. `{k.name} = {ex}`.")]
    return []


def _in_range(k: Key, v) -> bool:
    if k.lo is not None and (v <= k.lo if k.lo_open else v < k.lo):
        return False
    if k.hi is not None and (v >= k.hi if k.hi_open else v > k.hi):
        return False
    return True


def _fmt(v) -> str:
    if isinstance(v, str):
        return f'"{v}"'
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return f"{v:g}"
    if isinstance(v, list | tuple):
        return "[" + ", ".join(_fmt(x) for x in v) + "]"
    return str(v)


def _suggest(name: str, names) -> str:
    m = difflib.get_close_matches(str(name), [str(n) for n in names], n=1, cutoff=0.6)
    return f" Did you mean {m[0]!r}?" if m else ""


def _cross_checks(out: dict[str, Any]) -> list[Problem]:
    p: list[Problem] = []
    p += _cone_checks(out["material"])
    w = out["wall"]
    if "mu_kinetic" in w and w["mu_kinetic"] > w["mu_static"]:
        p.append(Problem("wall", "mu_kinetic", f"= {_fmt(w['mu_kinetic'])} exceeds mu_static = "
                         f"{_fmt(w['mu_static'])}. Fix: mu_kinetic ≤ mu_static."))
    if w["friction"] == "none" and w["regularisation_length"] > 0.0:
        p.append(Problem("wall", "regularisation_length", f"= {_fmt(w['regularisation_length'])} m on a "
                         "smooth wall (friction = \"none\"): there is no friction limit to give a memory. "
                         "Fix: remove the key, or choose friction = \"coulomb\" or \"velocity_dependent\"."))
    a = out["ale"]
    tot = a["laplacian_weight"] + a["mid_area_weight"]
    if not 0.0 < tot <= 1.0 + 1e-12:
        p.append(Problem("ale", "mid_area_weight", f"laplacian_weight + mid_area_weight = {tot:g}: "
                         "must be in (0, 1]. Fix: e.g. laplacian_weight = 0.5, mid_area_weight = 0.5."))
    d = out["discharge"]
    if 0.0 < a["rezone_min_quality"] <= d["min_mesh_quality"]:
        p.append(Problem("ale", "rezone_min_quality", f"= {_fmt(a['rezone_min_quality'])} is not above "
                         f"discharge.min_mesh_quality = {_fmt(d['min_mesh_quality'])}: the discharge would end before "
                         "the mesh is made again. Fix: rezone_min_quality above it (e.g. 0.3), or 0 (never)."))
    if d["mode"] != "none" and d["duration"] <= 0.0:
        p.append(Problem("discharge", "duration", f"= {_fmt(d['duration'])} with mode = "
                         f"{d['mode']!r}: a discharge needs a positive duration. Fix: e.g. "
                         "duration = 10.0, or mode = \"none\"."))
    if out["fill"]["method"] != "k0" and out["fill"]["duration"] <= 0.0:
        p.append(Problem("fill", "duration", "= 0: filling by layers or ramp needs time. Fix: e.g. "
                         "duration = 10.0, or method = \"k0\" to start from a geostatic state."))
    return p


# The return map's range: tan β < 3 keeps a cohesionless fill's active ratio (3 − tan β)/(3 + 2 tan β)
# positive; 70° leaves a margin.
BETA_MAX = 70.0
PHI_MAX = 60.0  # Mohr-Coulomb angles beyond this are not granular solids (compression cone: β 67.7°)


def _cone_checks(m: dict[str, Any]) -> list[Problem]:
    """φ and ψ against each other and, mapped by ``cone``, against the return map's range."""
    if "friction_angle" not in m:
        return []
    from silo_dolfinx.theory import drucker_prager_cone

    phi, psi, cone = m["friction_angle"], m["dilation_angle"], m.get("cone")
    if psi > phi:
        return [Problem("material", "dilation_angle", f"= {_fmt(psi)} exceeds friction_angle = {_fmt(phi)}: "
                        "dilation may not exceed friction (that would create energy). Fix: dilation_angle "
                        "≤ friction_angle (equal = associated flow).")]
    if cone != "beta" and phi > PHI_MAX:
        return [Problem("material", "friction_angle", f"= {_fmt(phi)}° with cone = {cone!r}: a Mohr-Coulomb "
                        f"angle must be in (0, {PHI_MAX:g}]°. Fix: e.g. `friction_angle = 30`, or cone = "
                        "\"beta\" if the angle is a Drucker-Prager slope.")]
    if cone is None:  # mohr_coulomb: no cone to map to (φ's range is the schema's)
        return []
    beta, _ = drucker_prager_cone(phi, psi, cone)
    if beta >= BETA_MAX:
        return [Problem("material", "friction_angle", f"= {_fmt(phi)}° maps to the Drucker-Prager slope β = "
                        f"{beta:.2f}° under cone = {cone!r}, beyond the return map's range (β < {BETA_MAX:g}°). "
                        "Fix: a smaller friction_angle, or another cone.")]
    return []


def _resolve_derived(out: dict[str, Any]) -> list[Problem]:
    """Defaults that depend on other keys (geometry-derived ones are set by the geometry layer)."""
    p: list[Problem] = []
    f = out["fill"]
    if f.get("k0") is DERIVED:
        nu = out["material"]["poisson_ratio"]
        f["k0"] = nu / (1.0 - nu)
    o = out["output"]
    g = out["geometry"]
    if o["stations"] is DERIVED:
        _default_stations(o, g)
    else:
        from silo_dolfinx.geometry.shapes import outline_from_geometry

        ol = outline_from_geometry(g)
        top = g["fill_height"] if o["station_coordinate"] == "z" else ol.wall_length_below_fill
        for x in o["stations"]:
            if not 0.0 <= x <= top * (1 + 1e-12):
                name = "height" if o["station_coordinate"] == "z" else "wall arclength"
                p.append(Problem("output", "stations", f"station {x:g} m is outside the wetted wall: "
                                 f"the {name} must be in [0, {top:g}] m. Fix: remove it or use a value "
                                 "in that range."))
                break
    labels = o["station_labels"]
    if labels and len(labels) != len(o["stations"]):
        p.append(Problem("output", "station_labels", f"= {_fmt(labels)}: {len(labels)} names for {len(o['stations'])} "
                         "stations. Fix: give one name per station, in the order of `stations` (\"\" for an "
                         "unnamed one), or [] for heights only."))
    p += _point_checks(o, g)
    return p


def _default_stations(o: dict, g: dict) -> None:
    """Ten stations evenly spaced on the wetted wall (heights or arclengths), and on a wall
    with a transition (a bin-hopper's corner, or its fillet's middle) a station there,
    named "transition" unless the scene names the stations itself: the switch stress that
    peaks there is the load a designer checks first (thesis ch. 7), and evenly spaced
    stations step over it."""
    from silo_dolfinx.geometry.shapes import outline_from_geometry

    ol = outline_from_geometry(g)
    by_height = o["station_coordinate"] == "z"
    top = g["fill_height"] if by_height else ol.wall_length_below_fill
    stations = [round(top * (i + 0.5) / 10, 6) for i in range(10)]
    if len(ol.transition_points):
        zt = float(ol.transition_points[len(ol.transition_points) // 2][1])
        x = round(zt if by_height else float(ol.wall.s_at_height(zt)[0]), 6)
        if x < top and x not in stations:
            stations = sorted(stations + [x])
            if not o["station_labels"]:
                o["station_labels"] = ["transition" if s == x else "" for s in stations]
    o["stations"] = stations


def _point_checks(o, g) -> list[Problem]:
    """Interior history points must lie in the fill: 0 ≤ z ≤ fill height, 0 ≤ r < wall radius."""
    if not o.get("points"):
        return []
    from silo_dolfinx.geometry.shapes import outline_from_geometry

    ol = outline_from_geometry(g)
    hf = g["fill_height"]
    for r, z in o["points"]:
        rw = float(ol.wall.radius_at(min(max(z, 0.0), hf))[0]) if 0.0 <= z <= hf else 0.0
        if not (0.0 <= z <= hf and 0.0 <= r < rw):
            return [Problem("output", "points", f"point [{r:g}, {z:g}] m is outside the fill (z in [0, {hf:g}] m, "
                            f"r in [0, wall radius) there). Fix: move it inside or remove it.")]
    return []


# What the keys imply for the run, checked before anything is meshed: each bound is far from any
# silo (the thesis' scenes sit 5-100 times inside it), so what trips one is a unit or exponent slip.
MAX_SELF_WEIGHT_STRAIN = 0.25  # the thesis' fills compress by ~0.05 of their height
MAX_DRIVE_STRAIN = 0.1  # the thesis' fastest controlled outlet (ch. 7, 2 u0): u0 / c_d = 0.048
STEP_SIZE_FACTOR = 0.5  # Δt estimate from half the smallest target element size (cells near an outlet are smaller)


def _feasibility(out: dict[str, Any]) -> list[Problem]:
    """Self-weight strain, outlet drive against the wave speed, the estimated number of steps,
    cohesion against stiffness."""
    from silo_dolfinx.theory import confined_wave_speed

    m, g, lo, f, d, n = (out[k] for k in ("material", "geometry", "loads", "fill", "discharge", "numerics"))
    E, rho, hf = m["youngs_modulus"], m["density"], g["fill_height"]
    p: list[Problem] = []
    strain = (rho * lo["gravity"] * hf + lo["top_surcharge"]) / E
    if strain > MAX_SELF_WEIGHT_STRAIN:
        p.append(Problem("material", "youngs_modulus", f"= {E:g} Pa: under its weight and surcharge the fill would "
                         f"compress by {strain:.3g} of its height ((density · gravity · fill_height + top_surcharge) / "
                         f"youngs_modulus = ({rho:g} · {lo['gravity']:g} · {hf:g} + {lo['top_surcharge']:g}) / {E:g}), "
                         f"more than {MAX_SELF_WEIGHT_STRAIN:g}: no granular solid does, and small-strain elasticity "
                         "cannot follow it. Fix: check the units (youngs_modulus and top_surcharge in Pa, density in "
                         "kg/m³, gravity in m/s²).",
                         also=("material.density", "loads.gravity", "loads.top_surcharge", "geometry.fill_height")))
    c = confined_wave_speed(E, m["poisson_ratio"], rho)
    if d["mode"] == "controlled":
        if d["velocity"] > MAX_DRIVE_STRAIN * c:
            p.append(Problem("discharge", "velocity", f"= {d['velocity']:g} m/s is {d['velocity'] / c:.3g} of the "
                             f"solid's wave speed c_d = {c:.3g} m/s: the drive would strike the fill (a strain u0/c_d "
                             f"above {MAX_DRIVE_STRAIN:g} in the wave it starts), not discharge it. Fix: velocity "
                             f"≤ {MAX_DRIVE_STRAIN * c:.3g} m/s (check its units), or a stiffer / lighter solid.",
                             also=("material.youngs_modulus", "material.density")))
    if m.get("cohesion", 0.0) >= E:
        p.append(Problem("material", "cohesion", f"= {m['cohesion']:g} Pa is not below youngs_modulus = {E:g} Pa: "
                         "the solid could never yield. Fix: check its units (Pa), or use model = \"elastic\".",
                         also=("material.youngs_modulus",)))
    h = g["element_size"] * min(g["outlet_size_factor"], g["transition_size_factor"]) * STEP_SIZE_FACTOR
    durations = {"fill.duration": f["duration"] if f["method"] != "k0" else 0.0, "store.duration": out["store"]["duration"],
                 "discharge.duration": d["duration"] if d["mode"] != "none" else 0.0}
    dt = n["time_step_scale"] * h / c * math.sqrt(n["mass_scaling"])
    steps = sum(durations.values()) / dt
    if steps > n["max_steps"]:
        p.append(Problem("numerics", "max_steps", f"= {n['max_steps']:g} is exceeded: the scene needs about {steps:.3g} "
                         f"time steps ({sum(durations.values()):g} s of fill, store and discharge at Δt ≈ {dt:.3g} s, "
                         f"from element_size = {g['element_size']:g} m, youngs_modulus = {E:g} Pa, density = "
                         f"{rho:g} kg/m³, time_step_scale = {n['time_step_scale']:g}). Fix: check the units and "
                         "exponents of those keys and the durations, or raise max_steps if the run is meant.",
                         also=("geometry.element_size", "material.youngs_modulus", "material.density",
                               "numerics.time_step_scale", "numerics.mass_scaling", *(k for k, v in durations.items() if v))))
    return p
