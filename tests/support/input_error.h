// The check every bad-input test makes: the action throws an InputError whose message is one
// line, names the file (or option) and says what is wrong.
#pragma once

#include <gtest/gtest.h>

#include <string>

#include "workloads/error.h"

namespace rtsim::test {

template <class Action>
void expect_input_error(Action&& action, const std::string& names, const std::string& fragment) {
    try {
        action();
        ADD_FAILURE() << "no error for " << names << " (expected '" << fragment << "')";
    } catch (const InputError& e) {
        const std::string msg = e.what();
        EXPECT_NE(msg.find(names), std::string::npos) << msg;
        EXPECT_NE(msg.find(fragment), std::string::npos) << msg;
        EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    }
}

}  // namespace rtsim::test
