// The volume a mesh's faces enclose.
#pragma once

#include "lodforge/core/mesh.hpp"

namespace lodforge {

// Signed volume of the mesh's faces (fan-triangulated), model units³: what a closed, consistently oriented mesh
// encloses (positive when its faces point outward).
double signed_volume(const Mesh& mesh);

}  // namespace lodforge
