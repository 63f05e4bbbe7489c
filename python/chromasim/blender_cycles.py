"""Renders a `chromasim export-scene` glTF file in Blender Cycles (run inside Blender):

    blender -b --factory-startup --python python/chromasim/blender_cycles.py -- \\
        SCENE.glb OUT.exr SIZE_PX SAMPLES SEED

The geometry comes from Blender's glTF importer; the materials are rebuilt from the file's own
material factors and extras (docs/EXPORT_SCENE.md), so that Cycles sees chromasim's optical
model, not the importer's PBR approximation of it:
- coating: Lambertian (Diffuse BSDF) of the base colour;
- inner surface: a smooth dielectric (Glass BSDF, sharp) of the file's ior;
- markers: no refraction (Transparent BSDF) and Beer-Lambert absorption inside (Volume
  Absorption, from attenuationColor over attenuationDistance); the outer markers scatter back
  diffusely on entry (front faces) with probability `scatter_fraction`;
- LEDs: Lambertian emitters on their front (+z) face, black behind;
- frame and lens barrel: black.
The camera becomes Cycles' equidistant fisheye with the field of the camera's extras
(2 x half_fov_deg). Output: linear RGB OpenEXR (Standard view transform, no denoising, no
clamping, no glossy blur), box pixel filter.
"""

import json
import math
import struct
import sys

import bpy
import numpy as np

if not hasattr(np, "bool"):  # Blender 3.4's glTF importer uses np.bool (gone in numpy 1.24)
    np.bool = bool


def gltf_json(path):
    """The JSON chunk of a .glb file, or the whole .gltf file."""
    with open(path, "rb") as f:
        data = f.read()
    if data[:4] != b"glTF":
        return json.loads(data)
    length = struct.unpack("<I", data[12:16])[0]
    return json.loads(data[20:20 + length])


def new_material(name):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    nodes = m.node_tree.nodes
    nodes.clear()
    return m, m.node_tree, nodes.new("ShaderNodeOutputMaterial")


def node(tree, kind, **inputs):
    n = tree.nodes.new(kind)
    for key, value in inputs.items():
        n.inputs[key].default_value = value
    return n


def rgba(values):
    return (values[0], values[1], values[2], 1.0)


def front_or_back(tree, front, back):
    """A shader that is `front` on front faces and `back` on back faces."""
    geometry = tree.nodes.new("ShaderNodeNewGeometry")
    mix = tree.nodes.new("ShaderNodeMixShader")
    tree.links.new(geometry.outputs["Backfacing"], mix.inputs["Fac"])
    tree.links.new(front.outputs[0], mix.inputs[1])
    tree.links.new(back.outputs[0], mix.inputs[2])
    return mix


def absorption(tree, g):
    """Volume Absorption of KHR_materials_volume: sigma_c = -ln(colour_c) / distance (1/m)."""
    volume = g.get("extensions", {}).get("KHR_materials_volume", {})
    colour = volume.get("attenuationColor", [1.0, 1.0, 1.0])
    distance = volume.get("attenuationDistance", math.inf)
    sigma = [-math.log(max(c, 1e-12)) / distance for c in colour]
    density = max(sigma)
    if density <= 0:
        return None
    # Cycles: sigma_c = density (1 - colour_c).
    return node(tree, "ShaderNodeVolumeAbsorption",
                Color=rgba([1.0 - s / density for s in sigma]), Density=density)


def marker_material(g):
    m, tree, out = new_material(g["name"])
    clear = node(tree, "ShaderNodeBsdfTransparent", Color=(1, 1, 1, 1))
    surface = clear
    fraction = g.get("extras", {}).get("scatter_fraction", 0.0)
    if fraction > 0:
        base = g.get("pbrMetallicRoughness", {}).get("baseColorFactor", [1, 1, 1, 1])
        diffuse = node(tree, "ShaderNodeBsdfDiffuse", Color=rgba(base))
        scatter = tree.nodes.new("ShaderNodeMixShader")
        scatter.inputs["Fac"].default_value = fraction
        tree.links.new(clear.outputs[0], scatter.inputs[1])
        tree.links.new(diffuse.outputs[0], scatter.inputs[2])
        surface = front_or_back(tree, scatter, clear)  # scatters on entry only
    tree.links.new(surface.outputs[0], out.inputs["Surface"])
    volume = absorption(tree, g)
    if volume:
        tree.links.new(volume.outputs[0], out.inputs["Volume"])
    return m


def surface_material(g):
    """The material of a non-marker mesh (coating, inner surface, LEDs, frame)."""
    m, tree, out = new_material(g["name"])
    base = g.get("pbrMetallicRoughness", {}).get("baseColorFactor", [1, 1, 1, 1])
    extensions = g.get("extensions", {})
    emissive = g.get("emissiveFactor", [0, 0, 0])
    if "KHR_materials_transmission" in extensions:
        ior = extensions.get("KHR_materials_ior", {}).get("ior", 1.5)
        shader = node(tree, "ShaderNodeBsdfGlass", Color=(1, 1, 1, 1), IOR=ior)
        shader.distribution = "SHARP"
    elif max(emissive) > 0:
        strength = g.get("extras", {}).get("relative_radiance", 1.0)
        emission = node(tree, "ShaderNodeEmission", Color=rgba(emissive), Strength=strength)
        black = node(tree, "ShaderNodeBsdfDiffuse", Color=(0, 0, 0, 1))
        shader = front_or_back(tree, emission, black)
    else:
        shader = node(tree, "ShaderNodeBsdfDiffuse", Color=rgba(base))
    tree.links.new(shader.outputs[0], out.inputs["Surface"])
    return m


def set_camera(scene, gl, size):
    camera = next(o for o in scene.objects if o.type == "CAMERA")
    extras = gl["cameras"][0].get("extras", {})
    if extras.get("model") != "equidistant":
        raise SystemExit("blender_cycles: only the equidistant fisheye has a Cycles model; "
                         f"the file's camera is {extras.get('model')!r}")
    camera.data.type = "PANO"
    camera.data.cycles.panorama_type = "FISHEYE_EQUIDISTANT"
    camera.data.cycles.fisheye_fov = math.radians(2.0 * extras["half_fov_deg"])
    camera.data.clip_start = 1e-5
    scene.camera = camera
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.resolution_percentage = 100


def set_cycles(scene, samples, seed):
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device = "CPU"
    c.samples = samples
    c.seed = seed
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.blur_glossy = 0.0
    c.caustics_reflective = True
    c.caustics_refractive = True
    c.max_bounces = c.diffuse_bounces = c.glossy_bounces = 128
    c.transmission_bounces = c.transparent_max_bounces = 128
    c.volume_bounces = 0
    c.min_light_bounces = 3
    c.pixel_filter_type = "BOX"
    c.filter_width = 1.0
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    world = bpy.data.worlds.new("black")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    scene.world = world
    settings = scene.render.image_settings
    settings.file_format = "OPEN_EXR"
    settings.color_depth = "32"
    settings.color_mode = "RGB"


def main():
    argv = sys.argv[sys.argv.index("--") + 1:]
    path, out, size, samples, seed = argv[0], argv[1], int(argv[2]), int(argv[3]), int(argv[4])
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=path)
    gl = gltf_json(path)
    scene = bpy.context.scene
    by_name = {g["name"]: g for g in gl["materials"]}
    for obj in scene.objects:
        if obj.type == "LIGHT":  # files of older versions: point lights stood in for the LEDs
            bpy.data.objects.remove(obj)
            continue
        if obj.type != "MESH" or not obj.data.materials:
            continue
        g = by_name[obj.data.materials[0].name]
        is_marker = "KHR_materials_volume" in g.get("extensions", {})
        obj.data.materials[0] = marker_material(g) if is_marker else surface_material(g)
    set_camera(scene, gl, size)
    set_cycles(scene, samples, seed)
    scene.render.filepath = out
    bpy.ops.render.render(write_still=True)


main()
