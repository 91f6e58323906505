"""Render an octopaint export in Blender, headless, with Cycles on the CPU:
the OpenVDB volume as emission-absorption (the painter's own model) and
the glTF iso-surface as a lit mesh with its vertex colours.

    blender --background --factory-startup --python docs/export/blender_render.py -- \\
        VOLUME.vdb MESH.glb OUT_PREFIX [--samples N] [--size WxH]

Writes OUT_PREFIX_volume.png and OUT_PREFIX_mesh.png. The exports must be
made with `--up z` (Blender is +z up; its glTF importer turns glTF's +y up
itself) and the same --origin, so both land in the same place. Blender 3.4
(Debian's `blender`) is what docs/export.md's pictures were made with.
"""

import math
import sys

import bpy
import numpy
from mathutils import Vector

# Debian's Blender 3.4 runs its glTF importer against Debian's numpy 1.24,
# which removed the `numpy.bool` alias the importer still uses
# (io_scene_gltf2/blender/imp/gltf2_blender_mesh.py); give it back.
if "bool" not in numpy.__dict__:
    numpy.bool = bool


def args():
    argv = sys.argv[sys.argv.index("--") + 1 :]
    vdb, glb, prefix = argv[:3]
    samples, size = 64, (960, 540)
    rest = argv[3:]
    while rest:
        flag, value = rest[0], rest[1]
        rest = rest[2:]
        if flag == "--samples":
            samples = int(value)
        elif flag == "--size":
            w, h = value.split("x")
            size = (int(w), int(h))
        else:
            raise SystemExit(f"unknown option {flag}")
    return vdb, glb, prefix, samples, size


def setup_scene(samples, size):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.use_denoising = False
    scene.cycles.volume_step_rate = 0.25
    scene.cycles.volume_max_steps = 4096
    scene.render.resolution_x, scene.render.resolution_y = size
    scene.render.film_transparent = False
    scene.view_settings.view_transform = "Standard"
    world = bpy.data.worlds.new("world")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.02, 0.02, 0.025, 1.0)
    scene.world = world
    return scene


def volume_material():
    """Absorption with coefficient `density` plus emission density·color:
    what the painter composites along a ray."""
    mat = bpy.data.materials.new("paint volume")
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    density = nodes.new("ShaderNodeAttribute")
    density.attribute_name = "density"
    colour = nodes.new("ShaderNodeAttribute")
    colour.attribute_name = "color"
    absorb = nodes.new("ShaderNodeVolumeAbsorption")
    absorb.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    links.new(density.outputs["Fac"], absorb.inputs["Density"])
    emit = nodes.new("ShaderNodeEmission")
    links.new(colour.outputs["Color"], emit.inputs["Color"])
    links.new(density.outputs["Fac"], emit.inputs["Strength"])
    add = nodes.new("ShaderNodeAddShader")
    links.new(absorb.outputs[0], add.inputs[0])
    links.new(emit.outputs[0], add.inputs[1])
    out = nodes.new("ShaderNodeOutputMaterial")
    links.new(add.outputs[0], out.inputs["Volume"])
    return mat


def frame(scene, lo, hi):
    """A camera looking at the box [lo, hi] from the front, a little above."""
    centre = (lo + hi) / 2
    extent = (hi - lo).length
    cam_data = bpy.data.cameras.new("camera")
    cam_data.lens = 50
    cam_data.clip_start = extent * 1e-3
    cam_data.clip_end = extent * 100
    cam = bpy.data.objects.new("camera", cam_data)
    scene.collection.objects.link(cam)
    direction = Vector((0.35, -1.0, 0.45)).normalized()
    cam.location = centre + direction * extent * 1.25
    cam.rotation_euler = (-direction).to_track_quat("-Z", "Y").to_euler()
    scene.camera = cam
    return cam


def bounds(objs):
    pts = [o.matrix_world @ Vector(c) for o in objs for c in o.bound_box]
    lo = Vector((min(p.x for p in pts), min(p.y for p in pts), min(p.z for p in pts)))
    hi = Vector((max(p.x for p in pts), max(p.y for p in pts), max(p.z for p in pts)))
    return lo, hi


def main():
    vdb, glb, prefix, samples, size = args()

    scene = setup_scene(samples, size)
    bpy.ops.object.volume_import(filepath=vdb)
    vol = bpy.context.active_object
    vol.data.materials.append(volume_material())
    # The camera frames the surface (the volume's faint haze reaches
    # further); import it once to measure, then drop it.
    bpy.ops.import_scene.gltf(filepath=glb)
    meshes = [o for o in bpy.context.selected_objects if o.type == "MESH"]
    lo, hi = bounds(meshes)
    for o in meshes:
        bpy.data.objects.remove(o, do_unlink=True)
    frame(scene, lo, hi)
    scene.render.filepath = f"{prefix}_volume.png"
    bpy.ops.render.render(write_still=True)

    scene = setup_scene(samples, size)
    bpy.ops.import_scene.gltf(filepath=glb)
    meshes = [o for o in bpy.context.selected_objects if o.type == "MESH"]
    lo, hi = bounds(meshes)
    scene.world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.25, 0.27, 0.3, 1.0)
    sun = bpy.data.objects.new("sun", bpy.data.lights.new("sun", "SUN"))
    sun.data.energy = 3.0
    sun.rotation_euler = (math.radians(40), math.radians(10), math.radians(30))
    scene.collection.objects.link(sun)
    frame(scene, lo, hi)
    scene.render.filepath = f"{prefix}_mesh.png"
    bpy.ops.render.render(write_still=True)


main()
