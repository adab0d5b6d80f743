// Per object of the scene (viewer/gpu_objects.py SCENE_OBJECT_DTYPE, std430), indexed by the object id
// every vertex carries: what would otherwise be per-draw uniforms, so that one multi-draw
// draws them all (viewer/draw_list.py).

struct SceneObject {
    vec4 lo;      // xyz: world-space bounding box, low corner (the culling test, cull.comp);
                  // w: 1 for an emitter (never dropped for its size), else 0
    vec4 hi;      // xyz: high corner
    ivec4 info;   // x: material index; y: light-map layers a back face adds to its page (0: no back
                  // side); z: first index in the scene's index buffer; w: index count (0: no triangles)
};

layout(std430, binding = SCENE_OBJECT_BINDING) readonly buffer SceneObjectBuffer { SceneObject scene_objects[]; };
