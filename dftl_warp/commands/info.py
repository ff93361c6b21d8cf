"""``dftl-warp info SCENE``: what a USD stage holds for dftl-warp, without simulating it."""

from __future__ import annotations

from ..errors import WarningRoute, plural
from . import strict_json


def add_parser(sub):
    p = sub.add_parser(
        "info",
        help="describe a USD stage: hair prims, strands, particles, colliders, features, memory, gravity, units, frames",
        description="Read SCENE the way `dftl-warp simulate` does and describe what it would simulate.",
    )
    from ..output.paths import path_argument

    p.add_argument("scene", metavar="SCENE", type=path_argument("the USD stage to describe"),
                   help="USD stage (.usd, .usda, .usdc, .usdz)")
    p.add_argument("--prim", action="append", metavar="PATH", help="only the BasisCurves prims at or below PATH")
    p.add_argument("--json", action="store_true", help="print the description as JSON")
    from ..options import add_arguments

    # simulate's --guides: the features, hair-hair and memory then describe the guides it would simulate
    add_arguments(p, ("guides", "guide_method"))
    p.set_defaults(run=run)


#: the elastic prims' memory is measured on at most this many of their strands and scaled by particles
ELASTIC_SAMPLE_STRANDS = 256


def array_bytes(*objects) -> int:
    """Bytes of the Warp arrays held by ``objects`` (and by the dftl_warp objects, lists and dicts
    they hold, three levels down), each array once."""
    import warp as wp

    seen, total = set(), 0

    def visit(value, depth):
        nonlocal total
        if isinstance(value, wp.array):
            if id(value) not in seen:
                seen.add(id(value))
                total += value.capacity
        elif isinstance(value, (list, tuple)):
            for v in value:
                visit(v, depth)
        elif isinstance(value, dict):
            for v in value.values():
                visit(v, depth)
        elif depth > 0 and hasattr(value, "__dict__") and type(value).__module__.startswith("dftl_warp"):
            for v in vars(value).values():
                visit(v, depth - 1)

    for obj in objects:
        visit(obj, 3)
    return total


def device_bytes(scene, precision: str, correction: str = "prior") -> int:
    """Device memory (bytes) a simulation of ``scene``'s strands allocates: model, state, control
    and solver arrays, measured by building them on the CPU device with each prim's solver (the
    layout does not change the total). The elastic solver's (rest data, frames, tensions and its
    factorization's scratch, in its default float64 arithmetic: about 9x DFTL's per particle) is
    measured on up to :data:`ELASTIC_SAMPLE_STRANDS` strands of each prim and scaled by its particles."""
    import numpy as np

    from ..core.model import Model
    from ..simulation.settings import SimulationOptions, group_settings
    from ..solvers import make_solver

    defaults = SimulationOptions()
    plain, total = [], 0
    for i, c in enumerate(scene.curves):
        if c.guides:
            # a render prim is not simulated: its binding to the guides (docs/guides.md, "Memory":
            # 16 n + 40 B a strand of n vertices, the default blended frames and k <= 4 guides)
            total += 16 * c.num_points + 40 * c.num_strands
            continue
        if group_settings(scene, defaults, i).solver != "elastic":
            plain.append(c)
            continue
        k = min(int(c.num_strands), ELASTIC_SAMPLE_STRANDS)
        n = int(c.counts[:k].sum())
        model = Model.from_strands(c.points[:n], c.counts[:k], device="cpu", precision=precision)
        solver = make_solver(model, "elastic")
        sample = array_bytes(model, solver.state(), model.control(), solver)
        total += sample * c.num_points / max(n, 1)
    if plain:
        points = np.concatenate([c.points for c in plain])
        counts = np.concatenate([c.counts for c in plain])
        model = Model.from_strands(points, counts, device="cpu", precision=precision)
        solver = make_solver(model, "dftl", correction=correction)
        total += array_bytes(model, solver.state(), model.control(), solver)
    return int(round(total))


def feature_summary(scene, precision: str = "float32") -> dict:
    """Which features a simulation of ``scene`` runs, and their device memory: per strand (mean)
    and fixed (hair-hair grid, collider tables and meshes). Built on the CPU device, grouped like
    the simulation (by root-binding mesh)."""
    import numpy as np

    from ..core.model import Model
    from ..errors import UserError
    from ..usd.scene import transform_points
    from ..features import HairHair, feature_names, find, group_features, memory_estimate
    from ..features.hair_hair import with_rest_density

    groups: dict = {}
    for c in scene.curves:
        if c.guides:   # a render prim is not simulated: its guides carry the features
            continue
        groups.setdefault(c.root_mesh.path if c.root_mesh is not None else None, []).append(c)
    flags, per_strand, fixed, bound = set(), 0.0, 0, 0
    hair_hair = []
    time = scene.read_time
    for mesh, curves in groups.items():
        feats, widths = group_features(scene, curves, time)
        points = np.concatenate([transform_points(c.transform(time), c.points) for c in curves])
        counts = np.concatenate([c.counts for c in curves])
        authored_threshold = getattr(find(feats, HairHair), "threshold", None) is not None
        try:   # as simulate sets them up and refuses them: a hair-hair grid of too many nodes, say
            feats, peak = with_rest_density(feats, points, counts, widths)
            model = Model.from_strands(points, counts, device="cpu", precision=precision, widths=widths,
                                       features=feats)
        except ValueError as exc:
            raise UserError(f"{scene.source}: {exc}") from None
        flags |= model.feature_flags
        est = memory_estimate(model)
        per_strand += est["feature_bytes_per_strand"] * model.num_strands
        fixed += est["fixed_feature_bytes"]
        if mesh is not None:
            bound += model.num_strands
        hh = find(feats, HairHair)
        if hh is not None:
            hair_hair.append({"prims": [c.path for c in curves], "cell": float(hh.cell_size),
                              "repulsion": float(hh.repulsion), "friction": float(hh.friction),
                              "splat_interval": int(hh.splat_interval), "rest_volume_fraction": hh.rest_density,
                              "threshold": float(hh.threshold), "rest_peak": peak,
                              "threshold_authored": authored_threshold,
                              "grid_nodes": [int(n) for n in model.feature_data.grid_shape]})
    strands = max(sum(c.num_strands for c in scene.curves), 1)
    return {"flags": sorted(flags), "names": feature_names(flags), "bound_roots": bound,
            "feature_bytes_per_strand": per_strand / strands, "fixed_feature_bytes": int(fixed),
            "hair_hair": hair_hair}


def material_summary(scene, curve) -> dict:
    """A prim's elastic material (stage units), where it came from, and its bending length
    l_b = (EI / (rho A g))^(1/3) for the prim's mean hair radius, in stage units and metres."""
    import numpy as np

    from ..features.scene import widths_per_point
    from ..solvers.elastic_material import default_radius, stage_material

    info = scene.stage
    mat = stage_material(curve.material, info.meters_per_unit, info.kilograms_per_unit)
    w = widths_per_point(curve, scene.read_time)
    radius = float(np.mean(0.5 * w[w > 0])) if w is not None and np.any(w > 0) else default_radius(info.meters_per_unit)
    lb = mat.bending_length(radius, float(np.linalg.norm(scene.gravity)))
    return {"source": mat.source, "youngs_modulus": mat.youngs_modulus, "density": mat.density,
            "bend_stiffness": mat.bend_stiffness, "twist_stiffness": mat.twist_stiffness,
            "youngs_modulus_pa": mat.youngs_modulus * info.kilograms_per_unit / info.meters_per_unit,
            "density_kg_m3": mat.density * info.kilograms_per_unit / info.meters_per_unit ** 3,
            "radius": radius, "radius_from_widths": w is not None and bool(np.any(w > 0)),
            "bending_length": lb, "bending_length_m": lb * info.meters_per_unit,
            "rest_shape_points": curve.rest_points is not None,
            "bend_stiffness_scale": curve.bend_scale is not None}


def describe(scene, guides=None) -> dict:
    """A JSON-able description of a :class:`~dftl_warp.usd.scene.Scene`. Raises
    :class:`~dftl_warp.errors.UserError` where `simulate` would refuse the prims (an elastic prim
    with a zero-length segment). ``guides`` (a :class:`~dftl_warp.guides.scene.GuideSet`,
    ``simulate --guides``): the features, hair-hair and memory are those of the guides it simulates
    (plus the render strands' bindings), as ``simulate`` runs them."""
    import numpy as np

    from ..simulation.settings import SimulationOptions, group_settings

    from ..simulation.elastic_setup import check_rest_lengths

    info = scene.stage
    defaults = SimulationOptions()
    for i, c in enumerate(scene.curves):  # what `simulate` refuses, refused here the same way
        if group_settings(scene, defaults, i).solver == "elastic":
            check_rest_lengths(scene.source, c, c.points if c.rest_points is None else c.rest_points)
    counts = np.concatenate([c.counts for c in scene.curves])
    strands = int(counts.size)
    sim = scene if guides is None else guides.sim_scene   # what simulate runs
    simulated = sum(int(c.num_strands) for c in sim.curves)
    bindings = 0 if guides is None else sum(16 * scene.curves[r.index].num_points + 40 * scene.curves[r.index].num_strands
                                            for r in guides.renders)   # as device_bytes counts a render prim
    memory = {p: device_bytes(sim, p) + bindings for p in ("float32", "float64")}
    features = {p: feature_summary(sim, p) for p in ("float32", "float64")}
    feature_total = {p: f["feature_bytes_per_strand"] * max(simulated, 1) for p, f in features.items()}
    per_prim = {c.path: int(c.num_strands) for c in sim.curves}
    return {
        "file": scene.source,
        "up_axis": info.up_axis,
        "meters_per_unit": info.meters_per_unit,
        "time_codes_per_second": info.time_codes_per_second,
        "frames": None if info.start_time_code is None else [info.start_time_code, info.end_time_code],
        "default_prim": info.default_prim,
        "gravity": [float(g) for g in scene.gravity],
        "gravity_m_per_s2": float(np.linalg.norm(scene.gravity_si)),
        "strands": strands,
        "particles": int(counts.sum()),
        "vertices_per_strand": [int(counts.min()), float(counts.mean()), int(counts.max())],
        "simulated_strands": simulated,
        "guides": None if guides is None else {"method": guides.method, "count": guides.count,
                                               "render_strands": guides.num_render_strands},
        "device_bytes_per_strand": {p: (b + feature_total[p]) / max(strands, 1) for p, b in memory.items()},
        "device_bytes": {p: b + int(round(feature_total[p])) + features[p]["fixed_feature_bytes"]
                         for p, b in memory.items()},
        "features": features["float32"]["names"],
        "feature_flags": features["float32"]["flags"],
        "roots_bound_to_a_mesh": features["float32"]["bound_roots"],
        "hair_hair": features["float32"]["hair_hair"],
        "feature_bytes_per_strand": {p: f["feature_bytes_per_strand"] for p, f in features.items()},
        "feature_fixed_bytes": {p: f["fixed_feature_bytes"] for p, f in features.items()},
        "scene_feature_attributes": {k: (v.tolist() if hasattr(v, "tolist") else v) for k, v in scene.features.items()},
        "curves": [
            {
                "path": c.path,
                # what `simulate` runs the prim with when the command line sets no solver; a render
                # prim (``rel dftl:guides``) is not simulated: its guides are (docs/guides.md)
                "solver": None if c.guides else group_settings(scene, defaults, i).solver,
                "guides": list(c.guides),
                "type": c.type,
                "basis": c.basis if c.type == "cubic" else None,
                "wrap": c.wrap,
                "strands": c.num_strands,
                "simulated_strands": per_prim.get(c.path, 0),
                "particles": c.num_points,
                "animated_transform": c.animated,
                "settings": {k: v for k, v in vars(c.settings).items() if v is not None and k != "simulate"},
                "feature_attributes": dict(c.features),
                "root_mesh": c.root_mesh.path if c.root_mesh is not None else None,
                "material": material_summary(scene, c),
            }
            for i, c in enumerate(scene.curves)
        ],
        "colliders": [
            {"path": c.path, "kind": c.kind, "friction": c.friction, "animated_transform": c.animated}
            for c in scene.colliders
        ],
        "warnings": list(scene.warnings),
    }


def _threshold(h: dict) -> str:
    """The hair-hair threshold as info prints it: its value, and where it was not authored, whence."""
    return f"{h['threshold']:.3g}" + ("" if h["threshold_authored"] else ", the densest node at rest by default")


def _bytes(n: float) -> str:
    for unit in ("B", "KiB", "MiB", "GiB"):
        if n < 1024 or unit == "GiB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024
    return str(n)


def run(args) -> int:
    # Python warnings while describing (numpy's RuntimeWarnings on extreme sizes, ...) are the
    # description's warnings, naming the stage (in --json too), not Python's two lines on stderr
    with WarningRoute(where=args.scene) as route:
        return _describe(args, route)


def _describe(args, route) -> int:
    from ..usd.read import read_scene

    from ..output import provenance
    from .render import time_code

    scene = read_scene(args.scene, prims=args.prim)
    route.where = scene.source
    route.keep_in(scene.warnings)
    if scene.stage.start_time_code is not None and scene.stage.end_time_code is not None:
        from ..errors import UserError
        from ..simulation.settings import resolve_frames

        try:   # the stage's frames that simulate refuses without --start/--end (past +-1e15, ...): said
            resolve_frames(scene)
        except UserError as exc:
            scene.warnings.append(f"{exc} (simulate refuses the stage's own frames)")
    guides = None
    if args.guides is not None:   # as simulate picks them (its first frame: the time the scene was read at)
        from ..guides.scene import GuideSet

        guides = GuideSet(scene, scene.read_time, guides=args.guides, guide_method=args.guide_method)
    elif args.guide_method is not None:
        scene.warnings.append(f"--guide-method {args.guide_method} does nothing without --guides: ignored")
    d = describe(scene, guides)
    route.keep_in(d["warnings"])
    made = provenance.read(args.scene)  # an output of dftl-warp: how it was made
    if made is not None:
        d["provenance"] = made
    if args.json:
        print(strict_json.dumps(d, indent=2))
        return 0
    frames = "none authored (give --start/--end to simulate)" if d["frames"] is None else (   # 1000003, not 1e+06
        f"{time_code(d['frames'][0])}..{time_code(d['frames'][1])} at {d['time_codes_per_second']:g} per second")
    g = d["gravity"]
    print(f"{d['file']}")
    print(f"  units       {d['meters_per_unit']:g} m per unit, up axis {d['up_axis']}"
          + (f", defaultPrim {d['default_prim']}" if d["default_prim"] else ""))
    print(f"  frames      {frames}")
    print(f"  gravity     ({g[0]:g}, {g[1]:g}, {g[2]:g}) units/s^2 = {d['gravity_m_per_s2']:.3g} m/s^2")
    lo, mean, hi = d["vertices_per_strand"]
    print(f"  hair        {plural(d['strands'], 'strand')}, {plural(d['particles'], 'particle')}, "
          f"{lo}..{hi} vertices per strand (mean {mean:.1f})")
    if d["guides"] is not None:
        g_ = d["guides"]
        count = f"{g_['count'] * 100:g}%" if isinstance(g_["count"], float) else str(g_["count"])
        print(f"  guides      --guides {count} ({g_['method']}): {d['simulated_strands']} of "
              f"{plural(d['strands'], 'strand')} "
              f"simulated, {g_['render_strands']} render strands deformed from them; the features, hair-hair and "
              "memory below are the simulated guides'")
    if d["features"]:
        extra = d["feature_bytes_per_strand"]["float32"]
        fixed = d["feature_fixed_bytes"]["float32"]
        bound = f"; {d['roots_bound_to_a_mesh']} roots bound to a mesh" if d["roots_bound_to_a_mesh"] else ""
        per = "per simulated strand" if d["guides"] is not None else "per strand"
        print(f"  features    {', '.join(d['features'])} ({_bytes(extra)} {per} and {_bytes(fixed)} "
              f"fixed in float32{bound})")
        mpu = d["meters_per_unit"]
        for h in d["hair_hair"]:
            nodes = "x".join(str(n) for n in h["grid_nodes"])
            print(f"  hair-hair   {', '.join(h['prims'])}: cell {h['cell']:g} units, repulsion {h['repulsion']:g} "
                  f"units/s^2 ({h['repulsion'] * mpu:g} m/s^2) per unit density relative to the rest volume "
                  f"fraction {h['rest_volume_fraction']:.3g} (densest node at rest {h['rest_peak']:.3g}; threshold "
                  f"{_threshold(h)}), friction {h['friction']:g}/s, grid {nodes} nodes, "
                  f"rebuilt every {plural(h['splat_interval'], 'substep')}")
    else:
        # the bare step is DFTL's only where every prim runs DFTL
        bare = "; the step is the bare DFTL step" if {c["solver"] for c in d["curves"]} <= {"dftl", None} else ""
        if d["roots_bound_to_a_mesh"]:
            print(f"  features    roots bound to a mesh ({d['roots_bound_to_a_mesh']}){bare}")
        else:
            print(f"  features    none{bare}")
    per = d["device_bytes_per_strand"]
    print(f"  memory      {_bytes(per['float32'])} per strand in float32, {_bytes(per['float64'])} in float64 "
          f"(total {_bytes(d['device_bytes']['float32'])} / {_bytes(d['device_bytes']['float64'])}, "
          f"features included, with each prim's solver"
          + (", render prims as their guide bindings)" if any(c["guides"] for c in d["curves"]) else ")"))
    print(f"  curves      {plural(len(d['curves']), 'prim')}")
    for c in d["curves"]:
        kind = c["type"] + (f" {c['basis']}" if c["basis"] else "") + f", {c['wrap']}"
        extra = ", animated transform" if c["animated_transform"] else ""
        settings = "".join(f", dftl:{k}={v:g}" if isinstance(v, float) else f", dftl:{k}={v}"
                           for k, v in c["settings"].items())
        settings += "".join(f", {k}={v:g}" if isinstance(v, float) else f", {k}={v}"
                            for k, v in c["feature_attributes"].items())
        if c["root_mesh"]:
            settings += f", roots on {c['root_mesh']}"
        runs = (f"solver {c['solver']}" if c["solver"] is not None else
                f"not simulated: deformed from its guides {', '.join(c['guides'])}")
        if d["guides"] is not None and c["solver"] is not None:
            runs += f" on {c['simulated_strands']} of its strands (guides), the rest deformed from them"
        print(f"    {c['path']}: {plural(c['strands'], 'strand')}, {plural(c['particles'], 'particle')}, "
              f"{kind}{extra}{settings}; {runs}")
        m = c["material"]
        ei = "" if m["bend_stiffness"] is None else f", EI {m['bend_stiffness']:.4g}"
        extras = "".join(t for t, on in ((", restShapePoints", m["rest_shape_points"]),
                                         (", bendStiffnessScale ramp", m["bend_stiffness_scale"])) if on)
        radius = f"radius {m['radius'] * d['meters_per_unit'] * 1e6:.3g} um" + (
            "" if m["radius_from_widths"] else " (no widths: default)")
        print(f"      material  E {m['youngs_modulus']:.4g} ({m['youngs_modulus_pa']:.4g} Pa), density "
              f"{m['density']:.4g} ({m['density_kg_m3']:.4g} kg/m^3){ei}; from {m['source']}{extras}")
        print(f"      bending length {m['bending_length']:.4g} units = {m['bending_length_m']:.4g} m ({radius})")
    print(f"  colliders   {len(d['colliders'])}")
    for c in d["colliders"]:
        friction = "" if c["friction"] is None else f", friction {c['friction']:g}"
        extra = ", animated transform" if c["animated_transform"] else ""
        print(f"    {c['path']}: {c['kind']}{friction}{extra}")
    for w in d["warnings"]:
        if made is not None and "points are time-sampled (an animated groom)" in w:
            continue   # a dftl-warp output: its points are the simulated frames (the provenance below)
        print(f"  warning     {w}")
    if made is not None:
        print("  provenance")
        for line in provenance.lines(made):
            print("  " + line)
    return 0
