#!/usr/bin/env python3
"""Make the loader's seed corpus, fuzz/seeds/loader/ (run from the repository root).

- the scenes shipped in assets/scenes/*.gltf that fit in the fuzz runs' -max_len (64 KiB; the
  SPLASH-2 rooms, 120-170 KB, do not);
- features.gltf: a small scene using what those files do not (a node hierarchy with TRS and a
  matrix, u8 and u16 indices, a strided view, a camera, images from a data URI and a buffer
  view, a textured double-sided material, KHR_materials_emissive_strength);
- cornell.glb and features.glb: the same scenes packed as GLB (JSON chunk + BIN chunk);
- blender-*.glb: the scenes Blender's exporter wrote (tests/scenes/blender/, made by
  scripts/blender_scenes.py): PNG and JPEG textures in the BIN chunk, a node tree, several
  primitives, KHR_lights_punctual, KHR_materials_transmission, doubleSided.
"""
import base64
import glob
import json
import os
import shutil
import struct

OUT = "fuzz/seeds/loader"
MAX_LEN = 65536


def features():
    pos = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]
    pbytes = b"".join(struct.pack("<3f", *p) + struct.pack("<f", 0.0) for p in pos)  # stride 16
    i8 = bytes([0, 1, 2, 0, 2, 3])
    i16 = struct.pack("<6H", 0, 2, 1, 0, 3, 2)
    png = bytes.fromhex(
        "89504e470d0a1a0a0000000d4948445200000001000000010806000000"
        "1f15c4890000000d49444154789c6360f8cfc0f01f0005000201"
        "a3d1ba5b0000000049454e44ae426082"
    )
    buf = pbytes + i8 + b"\0\0" + i16 + png
    o_i8 = len(pbytes)
    o_i16 = o_i8 + 8
    o_png = o_i16 + 12
    b64 = lambda b: base64.b64encode(b).decode()
    return {
        "asset": {"version": "2.0", "generator": "radlab fuzz seed"},
        "extensionsUsed": ["KHR_materials_emissive_strength"],
        "scene": 0,
        "scenes": [{"nodes": [0, 3]}],
        "nodes": [
            {"name": "root", "children": [1, 2], "translation": [0, 0, 1],
             "rotation": [0, 0, 0.7071068, 0.7071068]},
            {"name": "floor", "mesh": 0, "scale": [2, 2, 1]},
            {"name": "lamp", "mesh": 1, "matrix": [1, 0, 0, 0, 0, -1, 0, 0, 0, 0, -1, 0, 0, 0, 2, 1]},
            {"name": "camera", "camera": 0, "translation": [0.5, 0.5, 4]},
        ],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.01}}],
        "meshes": [
            {"name": "floor", "primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]},
            {"name": "lamp",
             "primitives": [{"attributes": {"POSITION": 0}, "indices": 2, "material": 1, "mode": 4}]},
        ],
        "materials": [
            {"name": "floor", "doubleSided": True,
             "pbrMetallicRoughness": {"baseColorFactor": [0.7, 0.6, 0.5, 1], "baseColorTexture": {"index": 0}}},
            {"name": "lamp", "emissiveFactor": [1, 0.9, 0.8],
             "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 5}}},
        ],
        "textures": [{"source": 0, "sampler": 0}, {"source": 1}],
        "samplers": [{"magFilter": 9729, "wrapS": 10497}],
        "images": [{"bufferView": 3, "mimeType": "image/png"}, {"uri": "data:image/png;base64," + b64(png)}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
            {"bufferView": 1, "componentType": 5121, "count": 6, "type": "SCALAR"},
            {"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"},
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": len(pbytes), "byteStride": 16, "target": 34962},
            {"buffer": 0, "byteOffset": o_i8, "byteLength": 6, "target": 34963},
            {"buffer": 0, "byteOffset": o_i16, "byteLength": 12, "target": 34963},
            {"buffer": 0, "byteOffset": o_png, "byteLength": len(png)},
        ],
        "buffers": [{"byteLength": len(buf), "uri": "data:application/octet-stream;base64," + b64(buf)}],
    }


def glb(doc):
    """Pack a document whose single buffer is a base64 data: URI as GLB."""
    doc = json.loads(json.dumps(doc))
    (buf,) = doc["buffers"]
    header, payload = buf.pop("uri").split(",", 1)
    assert header.endswith(";base64"), "the buffer must be a base64 data: URI"
    bin_chunk = base64.b64decode(payload)
    json_chunk = json.dumps(doc, separators=(",", ":")).encode()
    json_chunk += b" " * (-len(json_chunk) % 4)
    bin_chunk += b"\0" * (-len(bin_chunk) % 4)
    total = 12 + 8 + len(json_chunk) + 8 + len(bin_chunk)
    return (struct.pack("<4sII", b"glTF", 2, total)
            + struct.pack("<I4s", len(json_chunk), b"JSON") + json_chunk
            + struct.pack("<I4s", len(bin_chunk), b"BIN\0") + bin_chunk)


os.makedirs(OUT, exist_ok=True)
for path in sorted(glob.glob("assets/scenes/*.gltf")):
    if os.path.getsize(path) <= MAX_LEN:
        shutil.copy(path, OUT)
feat = features()
with open(f"{OUT}/features.gltf", "w") as f:
    json.dump(feat, f, indent=1)
with open(f"{OUT}/features.glb", "wb") as f:
    f.write(glb(feat))
with open("assets/scenes/cornell.gltf") as f:
    cornell = json.load(f)
with open(f"{OUT}/cornell.glb", "wb") as f:
    f.write(glb(cornell))
for path in sorted(glob.glob("tests/scenes/blender/*.glb")):
    if os.path.getsize(path) <= MAX_LEN:
        shutil.copy(path, f"{OUT}/blender-{os.path.basename(path)}")
