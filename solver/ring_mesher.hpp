// Disks meshed in concentric rings: no preferred direction for the rim to inherit.
#pragma once

#include "mesh.hpp"

namespace softshock {

// A disk of the given radius in about target_elements triangles: a centre node, then rings of
// radius i dr (i = 1..K) carrying n_i ~ 2 pi r_i / s equally spaced nodes (s = 2 dr / sqrt(3),
// near-equilateral triangles), each ring turned by a pseudo-random fraction of its spacing, and
// neighbouring rings zipped together by angle. Gmsh's frontal meshes are a hexagonal lattice of
// one orientation inside, which imprints modes 6, 12, 18 on the rim; here the rim is a uniform
// ring and the defects where ring counts change are spread quasi-randomly around the disk.
// Deterministic; Morton-ordered and finalized.
Mesh mesh_disk_rings(double radius_m, int target_elements);

// The cylinder r <= radius, -thickness/2 <= z <= thickness/2 in about target_elements
// tetrahedra: mesh_disk_rings' disk extruded in an even number of layers (the mid-plane z = 0 is
// one of them, its rim the disk's) of prisms of aspect ~1, three tetrahedra each. Thin layers stay
// well shaped (Delaunay tetrahedra of a thin layer had slivers of aspect ratio 14-56 at 100k,
// measured), and the mesh of each layer is the 2-D default's. Morton-ordered and finalized.
Mesh mesh_cylinder_rings(double radius_m, double thickness_m, int target_elements);

}  // namespace softshock
