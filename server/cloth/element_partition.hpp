// The elements split for assembly on two threads: the vertices are cut in two halves by number
// (by position where that crosses far more elements), then into parts by recursive median
// bisection of the rest shape (along each subset's longest side); an element whose three
// vertices lie in one part belongs to it, the others (across a cut) are separators. Elements of
// different parts share no vertex, so their blocks and right-hand sides land in different rows
// and the parts can be assembled at the same time; the separators come after them. Every list
// keeps the elements' order.
#pragma once

#include <array>
#include <vector>

#include "cloth/element.hpp"

namespace hapticloth::cloth {

struct ElementPartition {
  std::vector<std::vector<int>> parts;
  std::vector<int> separators;
};

/// `parts` a power of two >= 1.
ElementPartition partition_elements(const std::vector<ElementRest>& elements,
                                    const std::vector<Vec3>& rest_positions, int parts);

}  // namespace hapticloth::cloth
