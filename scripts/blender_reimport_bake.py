#!/usr/bin/env python3
"""Re-import a radlab bake (`radlab solve SCENE --bake out.glb`) in Blender and check its colours.

Issue 17 §3: Blender re-imports the bake with the colours. Blender is a tool to check with, not a
dependency of radlab (not in CI). With the `bpy` module from PyPI (Blender as a Python module;
bpy 5.0 needs Python 3.11):

    python3 -m venv /tmp/bpyenv && /tmp/bpyenv/bin/pip install bpy
    cargo run --release --no-default-features -- solve builtin:cornell --bake /tmp/cornell.glb
    /tmp/bpyenv/bin/python scripts/blender_reimport_bake.py /tmp/cornell.glb

or with a Blender install: `blender -b -P scripts/blender_reimport_bake.py -- /tmp/cornell.glb`.

What it does: reads COLOR_0 and _RADIOSITY of every mesh straight from the GLB (its own parser,
below), imports the file into an empty Blender scene with `bpy.ops.import_scene.gltf`, and for
every mesh object checks that it has a colour attribute, reports its storage and the per-channel
range of its linear values, and compares each face corner's colour with COLOR_0 of the glTF
vertex it came from (Blender may store colours as 8-bit sRGB, so up to COLOR_TOL apart). It also
reports the `_RADIOSITY` attribute, the material's shader nodes and the `radlab` extras Blender
kept as the scene's custom property. Exit status 1 if a mesh lacks colours or a colour differs.

A lightmap bake (`--bake-lightmap SIZE`, an image in the file) is checked instead for the lightmap
on the second UV map: every mesh has two UV maps, the second equals TEXCOORD_1 (Blender flips v:
(u, 1 - v)), and the material's Image Texture node shows the file's image (SIZE x SIZE, sRGB)
through a UV Map node naming that second map.
"""

import json
import struct
import sys

# 8-bit sRGB storage: half a step near 1 is 0.5/255 in sRGB, about 0.0045 in linear; 0.01 leaves room.
COLOR_TOL = 0.01
# _RADIOSITY is f32 in the file and f32 in Blender: equal up to rounding.
RADIOSITY_REL_TOL = 1e-6


def read_glb(path):
    """JSON and binary chunk of a GLB file."""
    data = open(path, "rb").read()
    magic, version, length = struct.unpack_from("<4sII", data, 0)
    if magic != b"glTF" or version != 2 or length != len(data):
        raise SystemExit(f"{path}: not a GLB 2.0 file")
    json_len, json_type = struct.unpack_from("<II", data, 12)
    doc = json.loads(data[20 : 20 + json_len])
    bin_at = 20 + json_len
    bin_len, _ = struct.unpack_from("<II", data, bin_at)
    return doc, data[bin_at + 8 : bin_at + 8 + bin_len]


def vec3s(doc, blob, index):
    """A tightly packed VEC3 float accessor as a list of tuples."""
    return vecs(doc, blob, index, 3)


def vecs(doc, blob, index, n):
    """A tightly packed VEC`n` float accessor as a list of tuples."""
    acc = doc["accessors"][index]
    view = doc["bufferViews"][acc["bufferView"]]
    assert acc["componentType"] == 5126 and acc["type"] == f"VEC{n}" and "byteStride" not in view
    start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    flat = struct.unpack_from(f"<{n * acc['count']}f", blob, start)
    return [flat[i : i + n] for i in range(0, len(flat), n)]


def check_lightmap(doc, blob, objects):
    """The lightmap form: TEXCOORD_1 as Blender's second UV map, wired to the image. Failures."""
    import bpy
    failures = []
    size = doc["asset"]["extras"]["radlab"]["lightmap"]["size"]
    uv1 = {m["name"]: vecs(doc, blob, m["primitives"][0]["attributes"]["TEXCOORD_1"], 2) for m in doc["meshes"]}
    for obj in objects:
        mesh = obj.data
        name = mesh.name if mesh.name in uv1 else obj.name
        layers = [layer.name for layer in mesh.uv_layers]
        if len(layers) < 2 or name not in uv1:
            failures.append(f"{obj.name}: UV maps {layers}")
            continue
        want = uv1[name]
        got = [tuple(d.uv) for d in mesh.uv_layers[1].data]
        expect = [(want[loop.vertex_index][0], 1.0 - want[loop.vertex_index][1]) for loop in mesh.loops]
        worst = max(abs(a - b) for g, e in zip(got, expect) for a, b in zip(g, e))
        if worst > 1e-6:
            failures.append(f"{obj.name}: second UV map differs from TEXCOORD_1 by {worst:.2e}")
        print(f"  {obj.name}: {len(mesh.polygons)} faces; UV maps {layers}; max |UV 2 - TEXCOORD_1| {worst:.1e}")
        for slot in obj.material_slots:
            tex = [n for n in slot.material.node_tree.nodes if n.bl_idname == "ShaderNodeTexImage"]
            if len(tex) != 1 or tex[0].image is None:
                failures.append(f"{obj.name}: no image texture in {slot.material.name}")
                continue
            image = tex[0].image
            feeds = [link.from_node for link in tex[0].inputs["Vector"].links]
            uv_map = feeds[0].uv_map if feeds and feeds[0].bl_idname == "ShaderNodeUVMap" else None
            if uv_map != layers[1] or tuple(image.size) != (size, size) or image.colorspace_settings.name != "sRGB":
                failures.append(
                    f"{obj.name}: image {tuple(image.size)} {image.colorspace_settings.name} through UV map {uv_map}"
                )
    for mat in bpy.data.materials:
        for n in mat.node_tree.nodes if mat.node_tree else []:
            if n.bl_idname == "ShaderNodeTexImage":
                img = n.image
                feeds = [link.from_node for link in n.inputs["Vector"].links]
                via = ", ".join(f"{f.bl_idname} '{getattr(f, 'uv_map', '')}'" for f in feeds)
                print(
                    f"material '{mat.name}': image '{img.name}' {img.size[0]}x{img.size[1]} "
                    f"{img.colorspace_settings.name}, packed {img.packed_file is not None}, interpolation "
                    f"{n.interpolation}, extension {n.extension}, vector from {via}"
                )
    return failures


def channel_range(values):
    return [(min(v[c] for v in values), max(v[c] for v in values)) for c in range(3)]


def fmt_range(r):
    return "  ".join(f"{ch} [{lo:.4f}, {hi:.4f}]" for ch, (lo, hi) in zip("RGB", r))


def main(argv):
    if len(argv) != 1:
        raise SystemExit("usage: blender_reimport_bake.py BAKE.glb")
    path = argv[0]
    import bpy  # here, so that --help-like misuse fails before Blender loads

    doc, blob = read_glb(path)
    if "images" in doc:
        info = doc["asset"]["extras"]["radlab"]
        print(f"blender {bpy.app.version_string}; file {path}")
        print(f"lightmap bake: scene {info['scene']}, {info['patches']} patches, lightmap {info['lightmap']['size']}")
        bpy.ops.wm.read_factory_settings(use_empty=True)
        bpy.ops.import_scene.gltf(filepath=path)
        objects = sorted((o for o in bpy.data.objects if o.type == "MESH"), key=lambda o: o.name)
        print(f"imported {len(objects)} mesh objects (the file has {len(doc['meshes'])} meshes)")
        failures = check_lightmap(doc, blob, objects)
        if len(objects) != len(doc["meshes"]):
            failures.append("mesh count differs")
        if failures:
            print("FAILED: " + "; ".join(failures))
            return 1
        print("OK: every mesh re-imported with the lightmap on its second UV map")
        return 0
    file_colors, file_radiosity = {}, {}
    for mesh in doc["meshes"]:
        attrs = mesh["primitives"][0]["attributes"]
        file_colors[mesh["name"]] = vec3s(doc, blob, attrs["COLOR_0"])
        file_radiosity[mesh["name"]] = vec3s(doc, blob, attrs["_RADIOSITY"])
    info = doc["asset"]["extras"]["radlab"]
    print(f"blender {bpy.app.version_string}; file {path}")
    print(
        f"bake: scene {info['scene']}, method {info['method']}, {info['elements']} elements, "
        f"exposure {info['exposure']:.6g}, clipped elements {info['clipped_elements']}"
    )

    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=path)

    failures = []
    objects = sorted((o for o in bpy.data.objects if o.type == "MESH"), key=lambda o: o.name)
    print(f"imported {len(objects)} mesh objects (the file has {len(doc['meshes'])} meshes)")
    if len(objects) != len(doc["meshes"]):
        failures.append("mesh count differs")
    all_colors = []
    for obj in objects:
        mesh = obj.data
        name = mesh.name if mesh.name in file_colors else obj.name
        if not mesh.color_attributes:
            failures.append(f"{obj.name}: no colour attribute")
            print(f"  {obj.name}: NO colour attribute")
            continue
        attr = mesh.color_attributes[0]
        colors = [tuple(d.color[:3]) for d in attr.data]  # linear, whatever the storage
        all_colors += colors
        want = file_colors.get(name)
        worst = None
        if want is not None:
            if attr.domain == "CORNER":
                expect = [want[loop.vertex_index] for loop in mesh.loops]
            else:
                expect = [want[i] for i in range(len(mesh.vertices))]
            if len(mesh.vertices) != len(want):
                failures.append(f"{obj.name}: {len(mesh.vertices)} vertices, the file has {len(want)}")
            else:
                worst = max(abs(a - b) for got, exp in zip(colors, expect) for a, b in zip(got, exp))
                if worst > COLOR_TOL:
                    failures.append(f"{obj.name}: colours differ from COLOR_0 by up to {worst:.4f}")
        else:
            failures.append(f"{obj.name}: no mesh of that name in the file")
        rad = mesh.attributes.get("_RADIOSITY")
        rad_note = "no _RADIOSITY attribute"
        if rad is not None and want is not None and len(rad.data) == len(file_radiosity[name]):
            got = [tuple(d.vector) for d in rad.data]
            rel = max(
                abs(a - b) / max(abs(b), 1e-30)
                for g, e in zip(got, file_radiosity[name])
                for a, b in zip(g, e)
            )
            rad_note = f"_RADIOSITY ({rad.domain}, {rad.data_type}) rel. diff {rel:.1e}"
            if rel > RADIOSITY_REL_TOL:
                failures.append(f"{obj.name}: _RADIOSITY differs by {rel:.1e}")
        print(
            f"  {obj.name}: {len(mesh.vertices)} vertices, {len(mesh.polygons)} faces; colour "
            f"'{attr.name}' ({attr.domain}, {attr.data_type}) {fmt_range(channel_range(colors))}; "
            f"max |Blender - COLOR_0| {worst if worst is None else f'{worst:.4f}'}; {rad_note}"
        )
    if all_colors:
        print(f"all colours (linear): {fmt_range(channel_range(all_colors))}")
    for mat in bpy.data.materials:
        nodes = sorted(n.bl_idname for n in mat.node_tree.nodes) if mat.node_tree else []
        print(f"material '{mat.name}': {', '.join(nodes)}")
    extras = bpy.context.scene.get("radlab")
    if extras is None:
        print("scene custom property 'radlab': absent")
    else:
        print(f"scene custom property 'radlab': exposure {extras['exposure']:.6g}, units: {extras['units']}")
    if failures:
        print("FAILED: " + "; ".join(failures))
        return 1
    print("OK: every mesh re-imported with its colours")
    return 0


if __name__ == "__main__":
    args = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else sys.argv[1:]
    sys.exit(main(args))
