"""The forest as a web page: three.js draws it with the renderer's own GLSL (``treeform forest --html``).

``forest.html`` opens offline from the file system: three.js is vendored in the package
(``report/assets/three-modules.js``), ``forest_viewer.js`` builds the scene, and
``forest_data.js`` carries the trees, every species' RDM, colour cubemap, leaflet channels,
billboard points and ``wood.glb`` (base64), and the shaders: the relief impostor's and the
billboard cloud's fragment shaders are the very sources of :mod:`treeform.render.impostor` and
:mod:`treeform.render.cloud`, turned into GLSL ES 3.00 by :func:`glsl_es` (WebGL 2 has no
geometry shader: :data:`treeform.render.cloud.WEB_VS` draws the billboards as instanced quads).
Near trees (the switch distance) are billboard clouds over their instanced wood, far ones
relief impostors, and far crowns narrower than ``card_px`` pixels on the canvas their impostor
cards (``render_forest``'s own, as a GLB); the split is redone whenever the camera moves (drag to
turn, wheel to zoom). Colours are display colours, as the renderer shows them: the GLBs' textures
are sampled as they are, not decoded from sRGB.
"""

from __future__ import annotations

import base64
import json
import re
import shutil
from pathlib import Path

import numpy as np

__all__ = ["forest_page_writers", "glsl_es"]

_ES_HEADER = ("precision highp float;\nprecision highp int;\nprecision highp sampler2D;\n"
              "precision highp samplerCube;\nprecision highp sampler3D;\n")


def glsl_es(source: str) -> str:
    """A desktop GLSL 3.30 shader of the renderer as GLSL ES 3.00 for WebGL 2 (three.js adds ``#version``).

    The ``#version`` line gives way to precision statements, and every output but location 0
    (the id buffer the renderer reads back; a web page draws colour only) becomes a plain
    global, so its assignments stay valid.

    Examples
    --------
    >>> print(glsl_es("#version 330\\nlayout(location = 1) out vec4 f_ids;\\nvoid main() {}").splitlines()[-2])
    vec4 f_ids;
    """
    body = re.sub(r"^\s*#version 330\s*\n", "", source, count=1)
    body = re.sub(r"layout\(location\s*=\s*[1-9]\d*\)\s*out\s+", "", body)
    return _ES_HEADER + body


def _b64(a) -> str:
    return base64.b64encode(np.ascontiguousarray(a).tobytes()).decode("ascii")


def _glb_b64(write) -> str:
    """Base64 of the GLB that ``write(path)`` writes."""
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        return base64.b64encode(Path(write(Path(tmp) / "m.glb")).read_bytes()).decode("ascii")


def _species_data(s, cards=None) -> dict:
    import cv2

    from treeform.io.gltf import GlbNode, write_glb, write_glb_scene
    from treeform.render.cloud import leaflet_textures
    from treeform.render.impostor import relief_bounds, relief_box, wood_uniforms

    imp = s.impostor
    _, _, rmin, rmax = relief_bounds(imp.rdm)
    lo, hi = relief_box(imp.rdm, imp.opacity)
    og = imp.opacity
    wa, wb, wg, nwood = wood_uniforms(og) if og is not None else (None, None, None, 0)
    rgba, shade, geo, luma = leaflet_textures(imp.leaflets)  # as the renderer's CloudPass packs them
    face = min(128, imp.color.shape[1])
    color = np.stack([cv2.resize(f, (face, face), interpolation=cv2.INTER_AREA) for f in imp.color]) \
        if face != imp.color.shape[1] else imp.color
    return {
        "name": s.name, "radius": s.crown_radius,
        "box": [[float(x) for x in lo], [float(x) for x in hi]], "rmin": rmin, "rmax": rmax,
        "rdm": {"center": [float(x) for x in imp.rdm.center], "res": int(imp.rdm.resolution),
                "radii": _b64(imp.rdm.radii.astype("<f4"))},
        "color": {"face": int(face), "rgb": _b64(color.astype(np.uint8))},
        # the opacity grid as half floats (a 3D texture WebGL 2 filters linearly without an extension)
        # and its capsules of wood as the shader's two vec4 arrays, with their bark colour
        **({"opacity": {"res": int(og.resolution), "origin": [float(x) for x in og.origin],
                        "extent": float(og.extent), "sigma": _b64(og.sigma.astype("<f2")),
                        "nwood": int(nwood), "bark": [float(x) for x in og.bark],
                        "wood_a": [float(x) for x in wa.ravel()], "wood_b": [float(x) for x in wb.ravel()],
                        "wood_g": [float(x) for x in wg.ravel()]}} if og is not None else {}),
        "leaflet": {"size": int(rgba.shape[0]), "rgba": _b64(rgba), "shade": _b64(shade), "geo": _b64(geo), "luma": luma},
        "cloud": {"points": _b64(imp.cloud_points.astype("<f4")), "size": float(imp.cloud_size)},
        "wood": _glb_b64(lambda p: write_glb(imp.wood, p)),
        **({"cards": _glb_b64(lambda p: write_glb_scene([GlbNode(cards, unlit=True)], p))}
           if cards is not None else {}),
    }


def forest_page_writers(species: list, trees: np.ndarray, camera, *, switch_distance: float, area, lighting,
                        sky, ground, relief_steps: int, relief_refine: int, full_px: float, card_px: float = 0.0,
                        cards: list | None = None, title: str = "forest") -> list:
    """Writers (:class:`~treeform.io.outputs.StagedOutputs`) of ``forest.html``, ``forest_data.js`` and
    ``assets/`` (three.js, its licence, the viewer). Call on the thread that owns nothing GL: no GL is used.

    ``cards``: each species' impostor cards (unlit meshes, as ``render_forest`` draws them), drawn
    for far crowns narrower than ``card_px`` pixels on the page's canvas; None draws none."""
    from treeform.render import impostor as relief
    from treeform.render import cloud
    from treeform.report.eval_page import ASSETS

    data = {
        "species": [_species_data(s, None if cards is None else cards[k]) for k, s in enumerate(species)],
        "trees": _b64(np.asarray(trees, "<f4")), "trees_count": int(len(trees)),
        "switch_distance": float(switch_distance), "area": [float(a) for a in area], "full_px": float(full_px),
        "card_px": float(card_px) if cards is not None else 0.0,
        "relief_steps": int(relief_steps), "relief_refine": int(relief_refine), "cloud_ao": 0.3,
        "max_wood": relief.MAX_WOOD, "wood_groups": relief.MAX_WOOD // relief.WOOD_GROUP,
        "sky": [float(x) for x in sky[:3]], "ground": [float(x) for x in ground[:3]],
        "lighting": {"direction": [float(x) for x in lighting.world_direction(camera)], "key": list(lighting.key),
                     "sky": list(lighting.sky), "ground": list(lighting.ground)},
        "camera": {"position": list(camera.position), "target": list(camera.target), "fov": float(camera.fov_y),
                   "near": float(camera.near), "far": float(camera.far)},
        "shaders": {"relief_vs": glsl_es(relief._VS), "relief_fs": glsl_es(relief._FS),
                    "cloud_vs": glsl_es(cloud.WEB_VS), "cloud_fs": glsl_es(cloud._FS)},
    }
    cards_line = f", impostor cards for crowns under {card_px:g} px" if data["card_px"] > 0 else ""
    script = "window.__tf_forest = " + json.dumps(data, separators=(",", ":")) + ";\n"
    page = f"""<!doctype html>
<html><head><meta charset="utf-8"><title>treeform: {title}</title>
<style>body{{margin:0;font-family:sans-serif;background:#222;color:#ddd}}
#tf-viewer{{width:100vw;height:calc(100vh - 2.2em);display:block}} p{{margin:0.4em 0.8em}}</style></head>
<body><p>treeform forest: {len(trees)} trees, {len(species)} species; billboard clouds within
{switch_distance:g} m, relief-mapped impostors beyond{cards_line} (drag to turn,
wheel to zoom). three.js (MIT, assets/THREE_LICENSE).</p>
<canvas id="tf-viewer"></canvas>
<script src="assets/three-modules.js"></script><script src="forest_data.js"></script>
<script src="assets/forest_viewer.js"></script></body></html>
"""

    def assets(d: Path):
        (d / "assets").mkdir(exist_ok=True)
        for name in ("three-modules.js", "forest_viewer.js", "THREE_LICENSE"):
            shutil.copyfile(ASSETS / name, d / "assets" / name)

    return [assets, lambda d: (d / "forest_data.js").write_text(script), lambda d: (d / "forest.html").write_text(page)]
