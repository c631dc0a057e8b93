// LoopMailboxes: the loops' handoff to the Hub's publisher, without threads.
#include <gtest/gtest.h>

#include "support/alloc_counter.hpp"
#include "cloth/mesh.hpp"
#include "cloth/model.hpp"
#include "haptics/loop/tactile_rendering.hpp"
#include "support/fixtures.hpp"
#include "transport/loop_mailboxes.hpp"

namespace hapticloth::transport {
namespace {

haptics::HapticReport report(std::uint64_t tick) {
  haptics::HapticReport r;
  r.tick = tick;
  r.time = tick * 1e-3;
  return r;
}

namespace {
hapticloth::devices::DeviceInfo device(int fingers) {
  hapticloth::devices::DeviceInfo d;
  d.fingers = fingers;
  return d;
}
}  // namespace

TEST(LoopMailboxes, SamplesComeOutInOrderAndAFullRingCountsTheRestAsDropped) {
  LoopMailboxes m(4, device(2), 60.0);
  const std::size_t n = LoopMailboxes::kSamples + 10;
  for (std::size_t k = 0; k < n; ++k) m.put_tick(report(k), devices::DeviceState{}, devices::DeviceCommand{});
  EXPECT_EQ(m.samples_dropped(), 10u);
  std::vector<HapticSample> out;
  out.reserve(LoopMailboxes::kSamples);
  m.take_samples(out);
  ASSERT_EQ(out.size(), LoopMailboxes::kSamples);
  for (std::size_t k = 0; k < out.size(); ++k) ASSERT_EQ(out[k].tick, k);
  out.clear();
  m.take_samples(out);
  EXPECT_TRUE(out.empty());
}

TEST(LoopMailboxes, TakeSamplesStopsAtTheCapacityReserved) {
  LoopMailboxes m(4, device(2), 60.0);
  for (std::uint64_t k = 0; k < 30; ++k) m.put_tick(report(k), devices::DeviceState{}, devices::DeviceCommand{});
  std::vector<HapticSample> out;
  out.reserve(20);
  const std::size_t cap = out.capacity();
  m.take_samples(out);
  EXPECT_EQ(out.size(), cap);
  EXPECT_EQ(out.capacity(), cap);
}

TEST(LoopMailboxes, TheClothComesAtMostAtTheClothRate) {
  LoopMailboxes m(1, device(2), 10.0);  // every 0.1 s
  haptics::ClothSnapshot s;
  s.resize(1);
  int frames = 0;
  for (int k = 0; k < 100; ++k) {  // 1 s of 10 ms steps
    s.time = k * 0.01;
    s.step = k;
    m.put_cloth(s);
    if (m.take_cloth()) ++frames;
  }
  EXPECT_EQ(frames, 10);
  EXPECT_EQ(m.take_cloth(), nullptr);
}

TEST(LoopMailboxes, WatchdogTripsCountFreshToStaleTransitions) {
  LoopMailboxes m(1, device(2), 60.0);
  devices::DeviceCommand stale, fresh, fault;
  stale.flags = devices::kFlagStale;
  fault.flags = devices::kFlagFault;
  // Stale from the start (no sample yet) is not a trip; each fresh -> stale is.
  for (const auto* c : {&stale, &fresh, &stale, &stale, &fresh, &fault, &stale})
    m.put_tick(report(0), devices::DeviceState{}, *c);
  EXPECT_EQ(m.watchdog_trips(), 2u);
  EXPECT_EQ(m.nan_forces(), 1u);
}

TEST(LoopMailboxes, TheLoopsSideDoesNotAllocate) {
  LoopMailboxes m(100, device(5), 60.0);
  haptics::ClothSnapshot s;
  s.resize(100);
  haptics::LoopStats ls;
  test::AllocationGuard guard;
  for (int k = 0; k < 5000; ++k) {  // past the ring's capacity: drops allocate nothing either
    m.put_tick(report(k), devices::DeviceState{}, devices::DeviceCommand{});
    s.time = k * 1e-3;
    m.put_cloth(s);
    if (k % 1000 == 0) m.put_stats(ls);
  }
  EXPECT_EQ(guard.count(), 0u);
}

// Two children of `n` vertices each, in a fan around their first vertex.
haptics::RefinedRegions two_children(int n) {
  haptics::RefinedRegions r;
  r.version = 1;
  for (int c = 0; c < 2; ++c) {
    const int first = static_cast<int>(r.x.size());
    for (int i = 0; i < n; ++i) r.x.push_back(Eigen::Vector3d(c, 1e-3 * i, 0.0));
    for (int i = 1; i + 1 < n; ++i) {
      r.triangles.push_back({first, first + i, first + i + 1});
      r.weave_uv.push_back({{{0.0, 0.0}, {1e-3 * i, 0.0}, {1e-3 * i, 1e-3}}});
    }
    r.region.push_back(10 * c);
  }
  return r;
}

TEST(LoopMailboxes, TheRefinedChildrenTravelWithTheNextClothFrames) {
  LoopMailboxes m(3, device(2), 1000.0);
  haptics::ClothSnapshot s;
  s.resize(3);
  const haptics::RefinedRegions r = two_children(5);
  m.put_refined(r);
  for (int k = 0; k < 2; ++k) {  // every frame carries the children until they change
    s.time = k * 1e-3;
    m.put_cloth(s);
    const LoopMailboxes::ClothFrame* f = m.take_cloth();
    ASSERT_NE(f, nullptr);
    ASSERT_EQ(f->refined_x.size(), 10u);
    ASSERT_EQ(f->refined_triangles.size(), 6u);
    ASSERT_EQ(f->refined_uv.size(), 6u);
    EXPECT_EQ(f->refined_region, (std::vector<std::int32_t>{0, 10}));
    EXPECT_FLOAT_EQ(f->refined_x[7][1], 2e-3f);
    EXPECT_EQ(f->refined_triangles[3], (std::array<std::int32_t, 3>{5, 6, 7}));  // the second child's
    EXPECT_FLOAT_EQ(f->refined_uv[4][2][0], 2e-3f);
  }
  m.put_refined(haptics::RefinedRegions{});  // the finger let go: the children are gone
  s.time = 2e-3;
  m.put_cloth(s);
  const LoopMailboxes::ClothFrame* f = m.take_cloth();
  ASSERT_NE(f, nullptr);
  EXPECT_TRUE(f->refined_x.empty());
  EXPECT_TRUE(f->refined_triangles.empty());
  EXPECT_TRUE(f->refined_region.empty());
}

TEST(LoopMailboxes, RefinedChildrenWithinTheReserveDoNotAllocate) {
  LoopMailboxes m(100, device(2), 60.0);
  haptics::ClothSnapshot s;
  s.resize(100);
  const haptics::RefinedRegions big = two_children(400), small = two_children(50);
  test::AllocationGuard guard;
  for (int k = 0; k < 300; ++k) {
    m.put_refined(k % 2 ? big : small);
    s.time = k * 1e-2;
    m.put_cloth(s);
  }
  EXPECT_EQ(guard.count(), 0u);
}


// The tactile output (a device with a display): every tick through the ring without allocating,
// with the display's layout and the fabric's periods for the messages; a device without a
// display gets no room and nothing to publish.
TEST(LoopMailboxes, TactileTicksPassWithTheirLayout) {
  cloth::GridSpec g;
  g.nx = g.ny = 2;
  cloth::Material mat = test::denim();
  mat.surface.weft = cloth::weave_profile(0.5e-3, 1e-5, cloth::WeaveShape::Sine);
  mat.surface.normalize_friction();
  const cloth::ClothModel model = cloth::build_model(cloth::make_grid(g), mat, {});
  devices::DeviceInfo d = device(2);
  d.tactile.vibration_rate = 4000;
  d.tactile.pin_rows = 6;
  d.tactile.pin_cols = 4;
  const haptics::TactileRendering rendering(model, d.tactile, 2, 1e-3, 0.008);
  LoopMailboxes m(4, d, 60.0, 0.5e-3, 0.8e-3);
  ASSERT_TRUE(m.has_tactile());
  EXPECT_EQ(m.tactile_layout().samples, 4);
  EXPECT_EQ(m.tactile_layout().rows * m.tactile_layout().cols, 24);
  EXPECT_FLOAT_EQ(m.tactile_layout().warp_period, 0.8e-3f);
  devices::TactileCommand c;
  c.finger[1].samples = 4;
  c.finger[1].vibration[2] = 3e-6f;
  {
    test::AllocationGuard guard;
    for (std::uint64_t k = 1; k <= 10; ++k) m.put_tactile(report(k), rendering, c);
    EXPECT_EQ(guard.count(), 0u);
  }
  std::vector<TactileSample> out;
  out.reserve(LoopMailboxes::kTactileSamples);
  m.take_tactile(out);
  ASSERT_EQ(out.size(), 10u);
  EXPECT_EQ(out[9].tick, 10u);
  EXPECT_EQ(out[0].out.finger[1].vibration[2], 3e-6f);
  EXPECT_EQ(m.tactile_dropped(), 0u);
  EXPECT_FALSE(LoopMailboxes(4, device(2), 60.0).has_tactile());
}

}  // namespace
}  // namespace hapticloth::transport
