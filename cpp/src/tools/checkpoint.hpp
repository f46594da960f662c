// A world's whole changing state as bytes, and back: the checkpoint a resumed run starts
// from. It holds the state, the step index, the broadphase and the contact store (warm
// start impulses, the contact cache with the offsets and rotations it was found at,
// scratch), so that a world restored from it takes the next steps bit-identically to the
// world it was saved from. The model
// and the settings are not in it: they come from the scene, and the checkpoint records
// only the sizes they fix (bodies, shapes, vertices), which load_checkpoint checks.
#pragma once

#include <cstdint>
#include <vector>

#include "rbsim/world.hpp"

namespace rbsim {

template <int D>
std::vector<std::uint8_t> save_checkpoint(const World<D>& world);
// The same in two parts: its size in bytes, then the bytes written at `out` (that many).
template <int D>
std::size_t checkpoint_size(const World<D>& world);
template <int D>
void save_checkpoint_to(const World<D>& world, std::uint8_t* out);

// Throws std::invalid_argument when the bytes are not a checkpoint of a world of this
// model's sizes (the world is then unchanged).
template <int D>
void load_checkpoint(World<D>& world, const std::uint8_t* data, std::size_t size);

}  // namespace rbsim
