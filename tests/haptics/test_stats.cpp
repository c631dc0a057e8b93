// The loops' histograms (server/haptics/stats): 1 us bins, quantiles and the fraction of values
// at or above a bound (the sim steps that waited on a slowed helper thread).
#include <gtest/gtest.h>

#include "haptics/loop/stats.hpp"

using hapticloth::haptics::Histogram;

TEST(Histogram, QuantilesAreBinCentresCappedByTheLargest) {
  Histogram h;
  EXPECT_EQ(h.quantile(0.5), 0.0);
  for (int i = 0; i < 100; ++i) h.add(i + 0.25);  // one value in each bin 0..99
  EXPECT_EQ(h.count(), 100u);
  EXPECT_EQ(h.quantile(0.5), 49.5);
  EXPECT_EQ(h.quantile(0.99), 98.5);
  EXPECT_EQ(h.quantile(1.0), 99.25);  // the top bin's centre is past the largest value
  h.add(-3.0);  // negative: counted in bin 0, so 2 of 101 values are below 1 us
  EXPECT_EQ(h.count(), 101u);
  EXPECT_EQ(h.quantile(0.015), 0.5);
}

TEST(Histogram, FractionAtLeastCountsTheBinsFromTheBound) {
  Histogram h;
  EXPECT_EQ(h.fraction_at_least(100.0), 0.0);
  for (double v : {0.0, 12.0, 99.9, 100.0, 150.0, 2e4}) h.add(v);  // 2e4: the top bin
  EXPECT_DOUBLE_EQ(h.fraction_at_least(100.0), 3.0 / 6.0);
  EXPECT_DOUBLE_EQ(h.fraction_at_least(0.0), 1.0);
  EXPECT_DOUBLE_EQ(h.fraction_at_least(99.0), 4.0 / 6.0);  // 99.9 is in bin 99
  EXPECT_DOUBLE_EQ(h.fraction_at_least(5e4), 1.0 / 6.0);   // beyond the bins: the top bin
}
