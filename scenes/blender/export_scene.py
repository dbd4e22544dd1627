# Builds one of our scene files (quads, triangles and spheres; diffuse, mirror and glass materials)
# in Blender and writes it with Blender's own exporters, the real clients of `penumbra solve FILE.glb`
# and `FILE.obj`:
#
#   blender -b --factory-startup --python scenes/blender/export_scene.py -- \
#       scenes/cornell-box.json scenes/blender/cornell-box.glb [scenes/blender/cornell-box.obj]
#
# Blender is Z-up and the glTF exporter turns it to glTF's Y-up, (x, y, z) -> (x, z, -y): a point
# (x, y, z) of our Y-up scene is placed at (x, -z, y), so that the file holds our coordinates, in
# metres (unit_scale applied). Materials: Principled BSDF, base colour = reflectance; a lamp's
# radiance as emission colour (its largest channel 1) times emission strength, which the exporter
# writes as emissiveFactor and KHR_materials_emissive_strength; a mirror metallic 1, roughness 0;
# glass transmission 1 with its IOR. Spheres become UV spheres (64 x 32), which the JSON cannot hold.
# The camera: vertical field of view and the scene's resolution. A diffuse reflectance_texture
# becomes an image texture node on the base colour, with the quads' texture coordinates (the OBJ then
# written with them and map_Kd). Used once to make the committed files (tests/test_import.cpp,
# tests/test_texture.cpp); CI does not run Blender.
import json
import math
import os
import shutil
import sys

import bpy
import mathutils

args = sys.argv[sys.argv.index("--") + 1:]
scene_path, glb_path = args[0], args[1]
obj_path = args[2] if len(args) > 2 else None
scene = json.load(open(scene_path))
textured = any("reflectance_texture" in m for m in scene["materials"].values() if isinstance(m, dict))
unit = scene.get("unit_scale", 1.0)

bpy.ops.wm.read_factory_settings(use_empty=True)
blender_scene = bpy.context.scene


def place(p):
    return (unit * p[0], -unit * p[2], unit * p[1])


materials = {}
for name, m in scene["materials"].items():
    if name.startswith("_"):
        continue
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    kind = m["type"]
    if kind == "diffuse":
        if "reflectance_texture" in m:
            # An image texture node on Base Color: the exporter writes baseColorTexture (the PNG
            # embedded in the .glb) and the OBJ exporter map_Kd. A factor beside it is not exported.
            if "reflectance" in m:
                raise SystemExit(f"{name}: a reflectance factor with a texture is not exported by this script")
            node = mat.node_tree.nodes.new("ShaderNodeTexImage")
            node.image = bpy.data.images.load(os.path.join(os.path.dirname(os.path.abspath(scene_path)),
                                                           m["reflectance_texture"]))
            mat.node_tree.links.new(node.outputs["Color"], bsdf.inputs["Base Color"])
        else:
            r = m["reflectance"]
            r = [r, r, r] if isinstance(r, (int, float)) else r
            bsdf.inputs["Base Color"].default_value = (r[0], r[1], r[2], 1)
        bsdf.inputs["Specular"].default_value = 0
        bsdf.inputs["Roughness"].default_value = 1
        if "emission" in m:
            e = m["emission"]
            e = [e, e, e] if isinstance(e, (int, float)) else e
            strength = max(e)
            bsdf.inputs["Emission"].default_value = (e[0] / strength, e[1] / strength, e[2] / strength, 1)
            bsdf.inputs["Emission Strength"].default_value = strength
    elif kind == "mirror":
        r = m.get("reflectance", [1, 1, 1])
        r = [r, r, r] if isinstance(r, (int, float)) else r
        bsdf.inputs["Base Color"].default_value = (r[0], r[1], r[2], 1)
        bsdf.inputs["Metallic"].default_value = 1
        bsdf.inputs["Roughness"].default_value = 0
    elif kind == "dielectric":
        bsdf.inputs["Base Color"].default_value = (1, 1, 1, 1)
        bsdf.inputs["Transmission"].default_value = 1
        bsdf.inputs["Roughness"].default_value = 0
        bsdf.inputs["IOR"].default_value = m["ior"]
    # Our materials are one-sided unless they say double_sided: Blender's backface culling is what
    # its glTF exporter writes as doubleSided false.
    mat.use_backface_culling = not m.get("double_sided", False)
    materials[name] = mat

for o in scene["objects"]:
    kind = o["type"]
    if kind in ("quad", "triangle"):
        verts = [place(v) for v in o["vertices"]]
        mesh = bpy.data.meshes.new(o["name"])
        mesh.from_pydata(verts, [], [list(range(len(verts)))])
        # Texture coordinates as our JSON gives them (default: the unit square from vertex 0);
        # Blender's v runs up the image, glTF's (and ours) down, which the exporter turns back.
        uv = o.get("uv", [[0, 0], [1, 0], [1, 1], [0, 1]] if kind == "quad" else [[0, 0], [1, 0], [0, 1]])
        layer = mesh.uv_layers.new(name="UVMap")
        for loop in mesh.loops:
            layer.data[loop.index].uv = (uv[loop.vertex_index][0], 1 - uv[loop.vertex_index][1])
        mesh.update()
        obj = bpy.data.objects.new(o["name"], mesh)
        blender_scene.collection.objects.link(obj)
    elif kind == "sphere":
        bpy.ops.mesh.primitive_uv_sphere_add(segments=64, ring_count=32, radius=unit * o["radius"],
                                             location=place(o["center"]))
        obj = bpy.context.active_object
        obj.name = o["name"]
        obj.data.name = o["name"]
        bpy.ops.object.shade_smooth()
    else:
        raise SystemExit(f"{o['name']}: type {kind} is not exported by this script")
    obj.data.materials.append(materials[o["material"]])

if "camera" in scene:
    c = scene["camera"]
    data = bpy.data.cameras.new("camera")
    data.sensor_fit = "VERTICAL"
    data.angle_y = math.radians(c.get("fov_y_deg", 40))
    cam = bpy.data.objects.new("camera", data)
    blender_scene.collection.objects.link(cam)
    cam.location = place(c["position"])
    forward = mathutils.Vector(place(c["look_at"])) - mathutils.Vector(place(c["position"]))
    if c.get("up", [0, 1, 0]) != [0, 1, 0]:
        raise SystemExit("camera: only up [0, 1, 0] is exported by this script")
    # The camera looks down its -Z with its +Y up, towards Blender's +Z (our +Y).
    cam.rotation_mode = "QUATERNION"
    cam.rotation_quaternion = forward.to_track_quat("-Z", "Y")
    blender_scene.camera = cam
    res = c.get("resolution", [512, 512])
    blender_scene.render.resolution_x, blender_scene.render.resolution_y = res[0], res[1]

bpy.ops.export_scene.gltf(filepath=glb_path, export_format="GLB", export_cameras=True, export_yup=True,
                          export_lights=False)
if obj_path:
    bpy.ops.wm.obj_export(filepath=obj_path, export_materials=True, forward_axis="NEGATIVE_Z", up_axis="Y",
                          export_uv=textured, export_normals=False, export_triangulated_mesh=False,
                          path_mode="STRIP")
    # map_Kd names the image alone (STRIP: the file is not saved, so RELATIVE has no folder to be
    # relative to): the images go beside the OBJ, as a user would hand them over.
    for image in bpy.data.images:
        if image.filepath:
            shutil.copy(bpy.path.abspath(image.filepath), os.path.dirname(os.path.abspath(obj_path)))
