#pragma once

#include <gtest/gtest.h>

#include <string>

#include "common/core/error.h"

namespace ag::test {

/// Expects `construct()` to throw ag::OptionError naming `field`: how every
/// options struct's Check() is tested.
template <class F>
void ExpectOptionErrorNaming(const std::string& field, F&& construct) {
  try {
    construct();
    ADD_FAILURE() << "expected an OptionError naming " << field;
  } catch (const OptionError& e) {
    EXPECT_EQ(e.field(), field) << e.what();
  }
}

}  // namespace ag::test
