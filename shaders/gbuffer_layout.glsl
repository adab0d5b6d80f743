// The G-buffer's render targets (viewer/passes/gbuffer.py allocates them; attachment numbers
// come in as defines GB_*):
//   GB_DIFFUSE   rgba32f  rgb: light-mapped diffuse radiance kd/pi * E (0 on dark back faces)
//   GB_NORMAL    rgba16f  xyz: unit shading normal on the side the viewer sees;
//                         w: GB_DARK_BACK_FACE on back faces of single-sided materials, else 0
//   GB_TANGENT   rgba16f  xyz: unit tangent orthogonal to the normal, or 0; w: bitangent sign
//   GB_MATERIAL  r32ui    material index
//   depth        24 bit   window depth; 1.0 (the clear value) = nothing drawn = sky

const float GB_DARK_BACK_FACE = 1.0;
