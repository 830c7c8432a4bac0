"""Author a small furnished interior in Blender and export it with Blender's own glTF exporter.

The scene families radlab generates (`radlab scenes --generate`) are written by radlab; this one
is made the way a user makes a room: Blender primitives moved, turned and scaled as objects,
bevel and array modifiers (applied by the exporter), linked duplicates (one mesh, several
nodes), n-gon caps the exporter triangulates, emissive materials for the lights.

    python -m venv /tmp/bpyenv && /tmp/bpyenv/bin/pip install bpy      # bpy 5.0.1, Python 3.11
    /tmp/bpyenv/bin/python scripts/blender_interior.py                # writes tests/scenes/blender/interior.glb

The room (5 × 4 × 2.7 m, a closed box facing inward) holds a table with four chairs (one chair
mesh, four nodes), a bookcase of arrayed books, a sofa, a rug (a plane 5 mm above the floor), a
floor lamp whose shade glows and a round ceiling light. Every material has Backface Culling on (glTF `doubleSided` false):
radlab's patches are one-sided. The camera is exported as the scene's viewpoint.
"""

import math
import os

import bpy
import bmesh  # noqa: E402 (only importable once bpy is)

OUT = os.path.normpath(
    os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "scenes", "blender", "interior.glb")
)

ROOM = (5.0, 4.0, 2.7)  # x, y (Blender's floor plane), z up


def material(name, base, emission=None, strength=1.0):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    m.use_backface_culling = True
    bsdf = m.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*base, 1.0)
    bsdf.inputs["Roughness"].default_value = 1.0
    if emission is not None:
        bsdf.inputs["Emission Color"].default_value = (*emission, 1.0)
        bsdf.inputs["Emission Strength"].default_value = strength
    return m


def assign(ob, mat):
    ob.data.materials.clear()
    ob.data.materials.append(mat)
    return ob


def box(name, centre, size, mat, rotation_z=0.0, bevel=0.0):
    """A cube primitive scaled to `size` (object scale, as a user drags it), optionally bevelled."""
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=centre, rotation=(0, 0, rotation_z))
    ob = bpy.context.active_object
    ob.name = name
    ob.scale = size
    if bevel > 0.0:
        bpy.ops.object.transform_apply(location=False, rotation=False, scale=True)
        mod = ob.modifiers.new("Bevel", "BEVEL")
        mod.width = bevel
        mod.segments = 2
    return assign(ob, mat)


def cylinder(name, centre, radius, depth, mat, vertices=12, cap="NGON"):
    bpy.ops.mesh.primitive_cylinder_add(vertices=vertices, radius=radius, depth=depth, location=centre,
                                        end_fill_type=cap)
    ob = bpy.context.active_object
    ob.name = name
    return assign(ob, mat)


def room(wall, floor, ceiling):
    """The room: a cube with its faces turned inward, the floor and ceiling their own materials."""
    w, d, h = ROOM
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(w / 2, d / 2, h / 2))
    ob = bpy.context.active_object
    ob.name = "Room"
    ob.scale = (w, d, h)
    bpy.ops.object.transform_apply(location=False, rotation=False, scale=True)
    for m in (wall, floor, ceiling):
        ob.data.materials.append(m)
    bm = bmesh.new()
    bm.from_mesh(ob.data)
    bmesh.ops.reverse_faces(bm, faces=bm.faces[:])
    for f in bm.faces:
        nz = f.normal.z
        f.material_index = 1 if nz > 0.5 else (2 if nz < -0.5 else 0)
    bm.to_mesh(ob.data)
    bm.free()
    return ob


def chair(wood, fabric):
    """One chair mesh (seat, four legs, back) joined into one object at the origin."""
    parts = [box("Seat", (0, 0, 0.45), (0.44, 0.42, 0.04), fabric)]
    for sx in (-1, 1):
        for sy in (-1, 1):
            parts.append(cylinder("Leg", (sx * 0.18, sy * 0.17, 0.215), 0.015, 0.43, wood, vertices=8))
    parts.append(box("Back", (0, 0.19, 0.72), (0.42, 0.03, 0.45), wood))
    bpy.ops.object.select_all(action="DESELECT")
    for p in parts:
        p.select_set(True)
    bpy.context.view_layer.objects.active = parts[0]
    bpy.ops.object.join()
    ob = bpy.context.active_object
    ob.name = "Chair"
    # The joined mesh in its own frame at the origin, unscaled, so that every node using it
    # places the same chair.
    bpy.ops.object.transform_apply(location=True, rotation=True, scale=True)
    return ob


def main():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    wall = material("wall", (0.7, 0.68, 0.62))
    floor = material("floor_wood", (0.42, 0.3, 0.2))
    ceiling = material("ceiling", (0.8, 0.8, 0.78))
    wood = material("wood", (0.55, 0.4, 0.26))
    dark = material("wood_dark", (0.3, 0.2, 0.14))
    fabric = material("fabric_blue", (0.2, 0.28, 0.5))
    sofa_fabric = material("fabric_green", (0.25, 0.45, 0.3))
    rug = material("rug_red", (0.55, 0.2, 0.18))
    metal = material("metal", (0.3, 0.3, 0.32))
    books = [material(f"book_{n}", c) for n, c in
             (("red", (0.6, 0.18, 0.16)), ("cream", (0.75, 0.7, 0.58)), ("black", (0.15, 0.15, 0.17)))]
    ceiling_light = material("ceiling_light", (0.8, 0.8, 0.8), emission=(1.0, 0.95, 0.85), strength=40.0)
    shade_light = material("shade_light", (0.7, 0.65, 0.55), emission=(1.0, 0.85, 0.6), strength=12.0)

    w, d, h = ROOM
    room(wall, floor, ceiling)
    bpy.ops.mesh.primitive_plane_add(size=1.0, location=(2.2, 2.0, 0.005))
    assign(bpy.context.active_object, rug).name = "Rug"
    bpy.context.active_object.scale = (2.2, 1.6, 1.0)

    # The table, bevelled top on four round legs, and four chairs: one mesh, four nodes.
    box("TableTop", (2.2, 2.0, 0.74), (1.4, 0.8, 0.04), wood, bevel=0.01)
    for sx in (-1, 1):
        for sy in (-1, 1):
            cylinder("TableLeg", (2.2 + sx * 0.62, 2.0 + sy * 0.32, 0.36), 0.03, 0.72, wood)
    proto = chair(dark, fabric)
    for k, (x, y, turn) in enumerate([(1.85, 1.45, 180), (2.55, 1.45, 180), (1.85, 2.55, 0), (2.55, 2.55, 0)]):
        ob = proto if k == 0 else bpy.data.objects.new(f"Chair.{k}", proto.data)
        if k > 0:
            bpy.context.scene.collection.objects.link(ob)
        ob.location = (x, y, 0)
        ob.rotation_euler = (0, 0, math.radians(turn + (7 if k % 2 else -5)))

    # A bookcase against the x = 0 wall; each shelf one arrayed row of books.
    case_x, case_y, case_w, case_d, case_h = 0.18, 2.0, 1.0, 0.34, 1.9
    for sy in (-1, 1):
        box("CaseSide", (case_x, case_y + sy * (case_w / 2 - 0.01), case_h / 2), (case_d, 0.02, case_h), wood)
    for s in range(5):
        z = 0.01 + s * 0.45
        box("CaseBoard", (case_x, case_y, z), (case_d, case_w - 0.04, 0.02), wood)
        if s < 4:
            book = box("Books", (case_x + 0.02, case_y - case_w / 2 + 0.04, z + 0.01 + 0.12),
                       (0.22, 0.03, 0.24), books[s % 3])
            mod = book.modifiers.new("Array", "ARRAY")
            mod.count = 22 - 3 * s
            mod.relative_offset_displace = (0, 1.3, 0)

    # The sofa against the y = 4 wall: seat, back and arms touching, not overlapping.
    box("SofaSeat", (3.6, 3.47, 0.22), (1.74, 0.62, 0.44), sofa_fabric, bevel=0.03)
    box("SofaBack", (3.6, 3.88, 0.45), (2.06, 0.2, 0.9), sofa_fabric, bevel=0.03)
    for sx in (-1, 1):
        box("SofaArm", (3.6 + sx * 0.95, 3.47, 0.3), (0.16, 0.62, 0.6), sofa_fabric, bevel=0.03)

    # A floor lamp in the corner: base, pole, a glowing open shade.
    cylinder("LampBase", (4.6, 0.4, 0.015), 0.15, 0.03, metal, vertices=16)
    cylinder("LampPole", (4.6, 0.4, 0.8), 0.012, 1.5, metal, vertices=8)
    bpy.ops.mesh.primitive_cone_add(vertices=16, radius1=0.22, radius2=0.14, depth=0.26,
                                    location=(4.6, 0.4, 1.45), end_fill_type="NOTHING")
    assign(bpy.context.active_object, shade_light).name = "LampShade"

    # A round ceiling light hung 2 cm below the ceiling, facing down.
    bpy.ops.mesh.primitive_circle_add(vertices=24, radius=0.3, fill_type="NGON", location=(2.2, 2.0, h - 0.02),
                                      rotation=(math.pi, 0, 0))
    assign(bpy.context.active_object, ceiling_light).name = "CeilingLight"

    bpy.ops.object.camera_add(location=(4.6, 3.6, 1.7), rotation=(math.radians(72), 0, math.radians(128)))
    bpy.context.scene.camera = bpy.context.active_object
    bpy.context.active_object.data.lens = 18.0

    bpy.ops.export_scene.gltf(
        filepath=OUT,
        export_format="GLB",
        export_yup=True,
        export_apply=True,
        export_cameras=True,
        export_lights=False,
        export_normals=False,
        export_texcoords=False,
        export_materials="EXPORT",
    )
    print(f"wrote {OUT}: {os.path.getsize(OUT)} bytes")


if __name__ == "__main__":
    main()
