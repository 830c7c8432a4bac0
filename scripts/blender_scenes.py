"""Author small scenes in Blender and export them with Blender's own glTF exporter.

Issue 17 §2: radlab reads glTF as Blender writes it. This script builds each scene from
scratch with `bpy` (Blender as a Python module, `pip install bpy`), exports it twice with
`bpy.ops.export_scene.gltf` (GLB, and glTF-separate: .gltf + .bin + image files), and writes
`expected.json` with what Blender itself says the scene is (world-space vertices of every mesh
object, in glTF's +Y-up frame). `tests/blender_gltf.rs` loads the files and checks them.

    python -m venv /tmp/bpyenv && /tmp/bpyenv/bin/pip install bpy
    /tmp/bpyenv/bin/python scripts/blender_scenes.py          # writes tests/scenes/blender/

Scenes (colours are sRGB bytes painted into the textures; see tests/blender_gltf.rs):
  room        textured floor (PNG, two halves of two colours, two quads), textured wall (JPEG,
              one colour), emissive ceiling panel (emission strength 5 > 1)
  hierarchy   empty → plane → cube, each with its own rotation, scale, translation
  materials   one cube with three materials (three primitives; one with transmission, an
              extension radlab does not support) and a second mesh
  light       a floor and a point light (KHR_lights_punctual)
  two_sided   one plane whose material shows its back face (doubleSided)
  shadow      a floor, a square occluder above it and a small square lamp above that (issue 16:
              the discontinuity meshes find its shadow's critical segments)

    /tmp/bpyenv/bin/python scripts/blender_scenes.py shadow   # only the named scenes; the
                                                              # others' entries of expected.json kept
"""

import json
import os
import sys
import tempfile
from math import radians

import bpy

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "scenes", "blender")
OUT = os.path.normpath(OUT)

FLOOR_LEFT = (200, 100, 50)  # sRGB bytes, u < 0.5
FLOOR_RIGHT = (50, 150, 220)  # u ≥ 0.5
WALL = (180, 160, 120)
TEX = 16  # texture size (16×16)


def reset():
    bpy.ops.wm.read_factory_settings(use_empty=True)


def srgb_image(name, path, fmt, colour_of_u):
    """A TEX×TEX image whose colour depends on u only, saved as `fmt` at `path`."""
    img = bpy.data.images.new(name, TEX, TEX, alpha=False)
    px = []
    for _y in range(TEX):
        for x in range(TEX):
            r, g, b = colour_of_u((x + 0.5) / TEX)
            px += [r / 255.0, g / 255.0, b / 255.0, 1.0]
    img.pixels = px
    img.filepath_raw = path
    img.file_format = fmt
    if fmt == "JPEG":
        bpy.context.scene.render.image_settings.quality = 100
    img.save()
    return img


def material(name, base=(0.5, 0.5, 0.5), image=None, emission=None, strength=1.0,
             transmission=0.0, two_sided=False):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    m.use_backface_culling = not two_sided  # exported as doubleSided = !use_backface_culling
    bsdf = m.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*base, 1.0)
    bsdf.inputs["Roughness"].default_value = 1.0
    if image is not None:
        tex = m.node_tree.nodes.new("ShaderNodeTexImage")
        tex.image = image
        m.node_tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    if emission is not None:
        bsdf.inputs["Emission Color"].default_value = (*emission, 1.0)
        bsdf.inputs["Emission Strength"].default_value = strength
    if transmission > 0.0:
        bsdf.inputs["Transmission Weight"].default_value = transmission
    return m


def mesh_object(name, verts, faces, mats=(), face_mats=None, uvs=None, parent=None):
    me = bpy.data.meshes.new(name)
    me.from_pydata(verts, [], faces)
    for m in mats:
        me.materials.append(m)
    if face_mats is not None:
        for poly, k in zip(me.polygons, face_mats):
            poly.material_index = k
    if uvs is not None:
        layer = me.uv_layers.new(name="UVMap")
        for poly in me.polygons:
            for li in poly.loop_indices:
                layer.data[li].uv = uvs(verts[me.loops[li].vertex_index])
    me.update()
    ob = bpy.data.objects.new(name, me)
    bpy.context.scene.collection.objects.link(ob)
    if parent is not None:
        ob.parent = parent
    return ob


def quad(x0, y0, x1, y1, z):
    """Vertices of an axis-aligned quad at height z, counter-clockwise seen from +z."""
    return [(x0, y0, z), (x1, y0, z), (x1, y1, z), (x0, y1, z)]


def cube(size):
    h = size / 2
    v = [(x, y, z) for x in (-h, h) for y in (-h, h) for z in (-h, h)]
    # outward-facing (counter-clockwise seen from outside)
    f = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return v, f


def yup(p):
    """Blender (Z up) → glTF (+Y up), as the exporter converts with export_yup."""
    return [p[0], p[2], -p[1]]


def world_vertices():
    bpy.context.view_layer.update()
    out = {}
    for ob in bpy.context.scene.objects:
        if ob.type == "MESH":
            out[ob.data.name] = [yup(ob.matrix_world @ v.co) for v in ob.data.vertices]
    return out


def export(name, lights=False):
    expected = world_vertices()
    for fmt, ext in (("GLB", "glb"), ("GLTF_SEPARATE", "gltf")):
        bpy.ops.export_scene.gltf(
            filepath=os.path.join(OUT, f"{name}.{ext}"),
            export_format=fmt,
            export_yup=True,
            export_apply=False,
            export_cameras=False,
            export_lights=lights,
            export_image_format="AUTO",
        )
    return expected


def room():
    reset()
    # The painted images are saved outside OUT; the exporter embeds them (GLB) or writes its
    # own copies next to the .gltf.
    tex_dir = tempfile.mkdtemp()
    floor_img = srgb_image("floor", os.path.join(tex_dir, "floor.png"), "PNG",
                           lambda u: FLOOR_LEFT if u < 0.5 else FLOOR_RIGHT)
    wall_img = srgb_image("wall", os.path.join(tex_dir, "wall.jpg"), "JPEG", lambda u: WALL)
    floor = material("floor", image=floor_img)
    wall = material("wall", image=wall_img)
    lamp = material("lamp", base=(0.2, 0.2, 0.2), emission=(1.0, 0.8, 0.6), strength=5.0)
    # Floor: two quads (x 0..1 and 1..2), y 0..2, UV u = x/2, v = y/2.
    fv = quad(0, 0, 1, 2, 0) + quad(1, 0, 2, 2, 0)
    mesh_object("Floor", fv, [(0, 1, 2, 3), (4, 5, 6, 7)], [floor],
                uvs=lambda p: (p[0] / 2, p[1] / 2))
    # Wall at y = 2 facing −y (into the room), x 0..2, z 0..2.
    wv = [(0, 2, 0), (2, 2, 0), (2, 2, 2), (0, 2, 2)]
    mesh_object("Wall", wv, [(0, 1, 2, 3)], [wall], uvs=lambda p: (p[0] / 2, p[2] / 2))
    # Ceiling panel at z = 1.9 facing down.
    pv = [(0.75, 0.75, 1.9), (0.75, 1.25, 1.9), (1.25, 1.25, 1.9), (1.25, 0.75, 1.9)]
    mesh_object("Panel", pv, [(0, 1, 2, 3)], [lamp])
    return export("room")


def hierarchy():
    reset()
    grey = material("grey")
    parent = bpy.data.objects.new("Parent", None)  # an empty
    bpy.context.scene.collection.objects.link(parent)
    parent.location = (1, 2, 3)
    parent.rotation_euler = (0, 0, radians(90))
    parent.scale = (2, 2, 2)
    child = mesh_object("ChildPlane", quad(-0.5, -0.5, 0.5, 0.5, 0), [(0, 1, 2, 3)], [grey],
                        parent=parent)
    child.location = (1, 0, 0)
    child.rotation_euler = (radians(90), 0, 0)
    child.scale = (0.5, 1.0, 0.5)
    v, f = cube(0.4)
    grand = mesh_object("GrandCube", v, f, [grey], parent=child)
    grand.location = (0, 0, 2)
    grand.rotation_euler = (0, radians(45), 0)
    return export("hierarchy")


def materials():
    reset()
    red = material("red", base=(0.8, 0.1, 0.1))
    green = material("green", base=(0.1, 0.7, 0.2))
    glass = material("glass", base=(0.9, 0.9, 0.9), transmission=1.0)
    v, f = cube(1.0)
    mesh_object("Blocks", v, f, [red, green, glass], face_mats=[0, 0, 1, 1, 2, 2])
    blue = material("blue", base=(0.1, 0.2, 0.6))
    mesh_object("Base", quad(-2, -2, 2, 2, -0.5), [(0, 1, 2, 3)], [blue])
    return export("materials")


def light():
    reset()
    grey = material("grey")
    mesh_object("Ground", quad(-1, -1, 1, 1, 0), [(0, 1, 2, 3)], [grey])
    data = bpy.data.lights.new("Bulb", "POINT")
    data.energy = 100.0
    ob = bpy.data.objects.new("Bulb", data)
    ob.location = (0, 0, 2)
    bpy.context.scene.collection.objects.link(ob)
    return export("light", lights=True)


def two_sided():
    reset()
    both = material("both", base=(0.6, 0.6, 0.6), two_sided=True)
    mesh_object("Sheet", quad(-1, -1, 1, 1, 0), [(0, 1, 2, 3)], [both])
    return export("two_sided")


def shadow():
    reset()
    grey = material("grey", base=(0.5, 0.5, 0.5))
    lamp = material("lamp", base=(0.0, 0.0, 0.0), emission=(1.0, 1.0, 1.0), strength=10.0)
    # Floor 2 × 2 at z = 0 facing up; occluder 0.5 × 0.5 at z = 0.5 facing the lamp; lamp
    # 0.2 × 0.2 at z = 1.5 facing down. Penumbra edges on the floor at |x|, |y| = 0.325 and 0.425.
    mesh_object("Floor", quad(-1, -1, 1, 1, 0), [(0, 1, 2, 3)], [grey])
    mesh_object("Occluder", quad(-0.25, -0.25, 0.25, 0.25, 0.5), [(0, 1, 2, 3)], [grey])
    mesh_object("Lamp", quad(-0.1, -0.1, 0.1, 0.1, 1.5), [(0, 3, 2, 1)], [lamp])
    return export("shadow")


SCENES = {
    "room": room,
    "hierarchy": hierarchy,
    "materials": materials,
    "light": light,
    "two_sided": two_sided,
    "shadow": shadow,
}


def main():
    os.makedirs(OUT, exist_ok=True)
    names = sys.argv[1:] or list(SCENES)
    path = os.path.join(OUT, "expected.json")
    expected = {"blender": bpy.app.version_string, "scenes": {}}
    if sys.argv[1:] and os.path.exists(path):
        with open(path) as f:
            expected = json.load(f)
    for name in names:
        expected["scenes"][name] = SCENES[name]()
        expected.setdefault("exported_by", {})[name] = bpy.app.version_string
    with open(os.path.join(OUT, "expected.json"), "w") as f:
        json.dump(expected, f, indent=1)
        f.write("\n")
    print(f"Blender {bpy.app.version_string}: scenes written to {OUT}", file=sys.stderr)


if __name__ == "__main__":
    main()
