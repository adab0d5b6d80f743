// Occlusion queries of planar reflectors (viewer/passes/mirror.py): the reflector's triangles are
// drawn against the G-buffer's depth with colour and depth writes off; only the count matters.

void main() {
}
