#include <gtest/gtest.h>
TEST(Empty, Compiles) {}
