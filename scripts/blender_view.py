"""Open a treeform GLB in Blender (the `bpy` module) as an artist would: facts as JSON, optional Cycles renders.

Blender's Python module pins its own numpy, so this runs in a separate environment:

    python3.11 -m venv .venv-blender && .venv-blender/bin/pip install bpy
    .venv-blender/bin/python scripts/blender_view.py out/demo/tree.glb --json facts.json \
        --render out/blender/demo --views front,side,three_quarter --size 512

facts.json: the imported objects, the scene's bounding box (Blender is Z-up: the glTF
importer turns treeform's Y-up metres into Z-up metres), each material's textures and alpha
set-up, the share of faces whose shading normals disagree with their winding (inside-out),
the animation (armatures, actions, how far the skinned mesh moves over the clip, the gap between
its first and last frame), and, per render, the share of the tree's pixels that came out black.
"""

from __future__ import annotations

import argparse
import json
import math
import sys


def _args(argv):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("glb")
    ap.add_argument("--json", help="write the facts here (default: stdout)")
    ap.add_argument("--render", help="render PNGs to PREFIX_<view>.png")
    ap.add_argument("--views", default="front,side,three_quarter")
    ap.add_argument("--size", type=int, default=384, help="render height in pixels")
    ap.add_argument("--samples", type=int, default=24)
    return ap.parse_args(argv)


def _material_facts(mat) -> dict:
    """What Blender made of a glTF material: image textures feeding colour / alpha / normal."""
    facts = {"name": mat.name, "base_color_image": None, "alpha_linked": False, "normal_map": False,
             "images": []}
    if not mat.use_nodes:
        return facts
    bsdf = next((n for n in mat.node_tree.nodes if n.type == "BSDF_PRINCIPLED"), None)
    for node in mat.node_tree.nodes:
        if node.type == "TEX_IMAGE" and node.image is not None:
            facts["images"].append({"name": node.image.name, "size": list(node.image.size)})
        if node.type == "NORMAL_MAP":
            facts["normal_map"] = True
    if bsdf is not None:
        base = bsdf.inputs["Base Color"]
        if base.is_linked:
            src = base.links[0].from_node
            while src.type != "TEX_IMAGE" and src.inputs and any(i.is_linked for i in src.inputs):
                src = next(i for i in src.inputs if i.is_linked).links[0].from_node
            if src.type == "TEX_IMAGE" and src.image is not None:
                facts["base_color_image"] = list(src.image.size)
        facts["alpha_linked"] = bsdf.inputs["Alpha"].is_linked
    return facts


def _inside_out(obj) -> float:
    """Share of faces whose corner (shading) normals point against the face's winding normal."""
    me = obj.data
    if not len(me.polygons):
        return 0.0
    corner = me.corner_normals
    bad = 0
    for p in me.polygons:
        s = [0.0, 0.0, 0.0]
        for li in p.loop_indices:
            v = corner[li].vector
            s[0] += v[0]
            s[1] += v[1]
            s[2] += v[2]
        if s[0] * p.normal[0] + s[1] * p.normal[1] + s[2] * p.normal[2] < 0:
            bad += 1
    return bad / len(me.polygons)


def _look_at(cam, target):
    import mathutils

    d = mathutils.Vector(target) - cam.location
    cam.rotation_euler = d.to_track_quat("-Z", "Y").to_euler()


def main(argv=None):
    import bpy
    import mathutils

    args = _args(sys.argv[1:] if argv is None else argv)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=args.glb)
    scene = bpy.context.scene
    meshes = [o for o in scene.objects if o.type == "MESH"]
    lo = [math.inf] * 3
    hi = [-math.inf] * 3
    for o in meshes:
        for c in o.bound_box:
            w = o.matrix_world @ mathutils.Vector(c)
            lo = [min(a, b) for a, b in zip(lo, w)]
            hi = [max(a, b) for a, b in zip(hi, w)]
    mats = {}
    for o in meshes:
        for slot in o.material_slots:
            if slot.material is not None and slot.material.name not in mats:
                mats[slot.material.name] = _material_facts(slot.material)
    facts = {
        "objects": [{"name": o.name, "faces": len(o.data.polygons), "inside_out": round(_inside_out(o), 5),
                     "materials": [s.material.name for s in o.material_slots if s.material]} for o in meshes],
        "bbox_min": lo, "bbox_max": hi, "materials": list(mats.values()), "renders": {},
    }
    facts["animation"] = _animation_facts(scene, meshes)
    if args.render:
        facts["renders"] = _render(scene, lo, hi, args)
    text = json.dumps(facts, indent=1)
    if args.json:
        with open(args.json, "w") as f:
            f.write(text)
    else:
        print(text)


def _animation_facts(scene, meshes) -> dict:
    """Armatures and actions the importer made, and how far the evaluated (skinned) mesh moves
    between the first frame, a quarter of the clip and its last frame."""
    import bpy

    actions = [{"name": a.name, "frames": [float(a.frame_range[0]), float(a.frame_range[1])]}
               for a in bpy.data.actions]
    out = {"armatures": sum(o.type == "ARMATURE" for o in scene.objects), "actions": actions}
    if not actions or not meshes:
        return out
    start, end = actions[0]["frames"]

    def verts(frame):
        scene.frame_set(int(round(frame)))
        dg = bpy.context.evaluated_depsgraph_get()
        pts = []
        for o in meshes:
            ev = o.evaluated_get(dg)
            me = ev.to_mesh()
            pts.extend((ev.matrix_world @ v.co).copy() for v in me.vertices)
            ev.to_mesh_clear()
        return pts

    a, b, c = verts(start), verts(start + 0.25 * (end - start)), verts(end)
    out["moved"] = max((p - q).length for p, q in zip(a, b))
    out["loop_gap"] = max((p - q).length for p, q in zip(a, c))
    return out


def _render(scene, lo, hi, args) -> dict:
    """Cycles renders of the tree from the front (-Y), the right (+X) and three-quarter above."""
    import bpy
    import numpy as np

    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = args.samples
    scene.cycles.use_denoising = True
    scene.render.film_transparent = True
    # the textures' own colours: Blender's default view transform (AgX) tone-maps them darker and greyer
    # (the Catalpa's front: photo crown mean RGB 0.32 / 0.47 / 0.23, AgX 0.31 / 0.39 / 0.24, Standard 0.31 / 0.43 / 0.26)
    scene.view_settings.view_transform = "Standard"
    h = args.size
    scene.render.resolution_y = h
    scene.render.resolution_x = int(round(h * 0.8))
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGBA"
    world = bpy.data.worlds.new("sky")
    world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (0.86, 0.88, 0.92, 1.0)  # an overcast sky, barely blue
    bg.inputs["Strength"].default_value = 0.9
    scene.world = world
    sun = bpy.data.objects.new("sun", bpy.data.lights.new("sun", "SUN"))
    sun.data.energy = 3.0
    sun.rotation_euler = (math.radians(50), 0, math.radians(30))
    scene.collection.objects.link(sun)
    cam = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.data.lens_unit = "FOV"
    cam.data.angle = math.radians(30)
    centre = [(a + b) / 2 for a, b in zip(lo, hi)]
    size = max(hi[2] - lo[2], hi[0] - lo[0], hi[1] - lo[1])
    dist = 1.15 * size / (2 * math.tan(math.radians(15)))
    views = {"front": (0.0, 0.0), "side": (90.0, 0.0), "three_quarter": (45.0, 20.0)}
    out = {}
    for name in args.views.split(","):
        az, el = views[name]
        a, e = math.radians(az), math.radians(el)
        # azimuth 0: in front (glTF +Z is Blender -Y), 90: from the right (+X)
        cam.location = (centre[0] + dist * math.sin(a) * math.cos(e), centre[1] - dist * math.cos(a) * math.cos(e),
                        centre[2] + dist * math.sin(e))
        _look_at(cam, centre)
        path = f"{args.render}_{name}.png"
        scene.render.filepath = path
        bpy.ops.render.render(write_still=True)
        img = bpy.data.images.load(path)
        px = np.array(img.pixels[:], dtype=np.float32).reshape(img.size[1], img.size[0], 4)
        tree = px[..., 3] > 0.5
        lum = px[..., :3] @ np.array([0.2126, 0.7152, 0.0722], np.float32)
        out[name] = {"path": path, "tree_pixels": int(tree.sum()),
                     "black_share": float((lum[tree] < 0.02).mean()) if tree.any() else 1.0,
                     "mean_rgb": px[..., :3][tree].mean(axis=0).round(4).tolist() if tree.any() else None}
        bpy.data.images.remove(img)
    return out


if __name__ == "__main__":
    main()
