// The haptic tick (server/haptics/haptic_loop): real-time safe, it allocates nothing.
#include <gtest/gtest.h>

#include "haptics/session.hpp"
#include "support/alloc_counter.hpp"
#include "support/touch_scenes.hpp"

using namespace hapticloth;
using haptics::Vec3;

// The haptic tick allocates nothing (device read/write, narrow phase, local patch or response
// model, proxy, gate, tactile rendering, handoff), also on the ticks after a global step's
// hand-over.
class TickAllocation : public ::testing::TestWithParam<haptics::Rendering> {};

TEST_P(TickAllocation, TickAllocatesNothing) {
  const double r = 0.008;
  haptics::SessionConfig sc;
  sc.rendering = GetParam();
  const bool multirate = haptics::multirate(sc.rendering);
  cloth::IntegratorConfig ic = test::sim_config(multirate ? 0.02 : 1e-3);
  // Pressing from the first tick (the script restarts when the device is reactivated).
  test::DrumRig rig(test::with_weave(test::drum()),
                    test::one_finger({{0.0, Vec3(0.003, 0.002, r - 0.003)}, {1.0, Vec3(0.013, 0.002, r - 0.003)}}), sc,
                    ic, test::tactile_device_options());
  auto& s = *rig.session;
  std::uint64_t allocs = 0, contact = 0;
  s.run_stepped(1.0, 0.0, [&](const haptics::HapticLoop&, const haptics::SimWorker&) {});
  // Now tick the haptic loop alone under the guard, at the state reached (in contact), with a
  // global step every 20 ticks.
  rig.dev.activate();
  auto& h = s.haptics();
  for (int k = 0; k < 500; ++k) {
    if (multirate && k % 20 == 0) s.sim().step(1.0 + 0.001 * k);
    test::AllocationGuard guard;
    h.tick(1.0 + 0.001 * k);
    allocs += guard.count();
    contact += h.last_report().finger[0].in_contact;
  }
  EXPECT_EQ(allocs, 0u);
  EXPECT_GT(contact, 400u);
  ASSERT_NE(h.tactile(), nullptr);
  EXPECT_GT(h.tactile()->counters().textured_ticks, 400u);
  if (GetParam() == haptics::Rendering::Patch) {
    EXPECT_GE(h.patch_rebuilds(), 1u);
  }
}

INSTANTIATE_TEST_SUITE_P(EachRendering, TickAllocation,
                         ::testing::Values(haptics::Rendering::Direct, haptics::Rendering::Patch,
                                           haptics::Rendering::Response));
