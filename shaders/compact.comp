// Compaction of one region's draw commands (viewer/draw_list.py, where the driver offers
// glMultiDrawElementsIndirectCount): per texture batch, the commands cull.comp wrote with instance
// count 1, in their order, packed to the front of the batch's range of the compact buffer, and
// their number in the batch's count, which the multi-draw reads on the GPU. So the driver walks
// only the draws that survived culling, not one per object. The order is kept (an exclusive
// prefix sum per chunk of COMPACT_GROUP commands: Hillis and Steele's scan in shared memory), so
// the pixels are those of the uncompacted multi-draw.
// Reads: the region's commands, the batches. Writes: the region's compact commands and counts.
// One work group per batch.

#include "common.glsl"
#include "draw_command.glsl"

layout(local_size_x = COMPACT_GROUP) in;

layout(std430, binding = DRAW_COMMAND_BINDING) readonly buffer DrawCommands { DrawCommand commands[]; };
layout(std430, binding = DRAW_COMPACT_BINDING) writeonly buffer CompactCommands { DrawCommand compact[]; };
layout(std430, binding = DRAW_COUNT_BINDING) writeonly buffer DrawCounts { uint draw_counts[]; };
layout(std430, binding = DRAW_BATCH_BINDING) readonly buffer DrawBatches { ivec2 batches[]; };  // first, count

uniform int first_command;  // this region's first command (region x object count)
uniform int first_count;    // this region's first count (region x batch count)

shared uint kept[COMPACT_GROUP];

void main() {
    int b = int(gl_WorkGroupID.x);
    ivec2 batch = batches[b];
    uint t = gl_LocalInvocationID.x;
    uint written = 0u;
    for (int start = 0; start < batch.y; start += COMPACT_GROUP) {  // the same trips for the whole group
        int c = start + int(t);
        DrawCommand command;
        uint keep = 0u;
        if (c < batch.y) {
            command = commands[first_command + batch.x + c];
            keep = command.instance_count != 0u ? 1u : 0u;
        }
        kept[t] = keep;
        barrier();
        for (uint step = 1u; step < uint(COMPACT_GROUP); step <<= 1) {  // inclusive scan
            uint add = t >= step ? kept[t - step] : 0u;
            barrier();
            kept[t] += add;
            barrier();
        }
        if (keep != 0u)
            compact[first_command + batch.x + int(written + kept[t] - 1u)] = command;
        written += kept[COMPACT_GROUP - 1];
        barrier();  // every invocation has read kept[] before the next chunk writes it
    }
    if (t == 0u)
        draw_counts[first_count + b] = written;
}
