// One glDrawElementsIndirect command (viewer/draw_list.py COMMAND_BYTES): cull.comp writes them,
// compact.comp packs the drawn ones.
struct DrawCommand {
    uint count;
    uint instance_count;
    uint first_index;
    int base_vertex;     // 0: the scene's index buffer holds global vertex indices
    uint base_instance;
};
