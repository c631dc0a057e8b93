// The HAL's fixed sizes: storage for every finger is fixed, so the real-time path never
// allocates.
#pragma once

namespace hapticloth::devices {

/// Most fingers a device may have.
inline constexpr int kMaxFingers = 5;
/// A pinch needs two fingers.
inline constexpr int kMinFingers = 2;

}  // namespace hapticloth::devices
