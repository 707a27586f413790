// MappableArray: a view reads what it was given and is never written through; anything that
// changes the array works on a copy of its own, and copies and moves keep both sides right.
#include <gtest/gtest.h>

#include <memory>
#include <vector>

#include "workloads/mappable_array.h"

using namespace rtsim;

namespace {

// Records "mapped" in a buffer that the test checks afterwards for writes.
struct Mapped {
    std::vector<int> bytes{10, 11, 12, 13};
    std::shared_ptr<const void> keep = std::make_shared<int>(0);
};

std::vector<int> contents(const MappableArray<int>& a) {
    return {a.begin(), a.end()};
}

}  // namespace

TEST(MappableArray, AViewReadsTheMappedRecords) {
    Mapped m;
    MappableArray<int> a;
    a.view(m.bytes.data(), 3, m.keep);
    EXPECT_TRUE(a.is_view());
    EXPECT_EQ(a.size(), 3u);
    EXPECT_EQ(a.data(), m.bytes.data());
    EXPECT_EQ(contents(a), (std::vector<int>{10, 11, 12}));
    EXPECT_EQ(a.at(2), 12);
    EXPECT_THROW(a.at(3), std::out_of_range);
}

TEST(MappableArray, ChangingAViewCopiesItFirst) {
    Mapped m;
    MappableArray<int> a;
    a.view(m.bytes.data(), 3, m.keep);
    a.mutable_at(1) = 99;
    a.push_back(7);
    EXPECT_FALSE(a.is_view());
    EXPECT_EQ(contents(a), (std::vector<int>{10, 99, 12, 7}));
    EXPECT_EQ(m.bytes, (std::vector<int>{10, 11, 12, 13}));  // the mapping is untouched
}

TEST(MappableArray, CopiesAndMovesKeepTheirRecords) {
    Mapped m;
    MappableArray<int> view;
    view.view(m.bytes.data(), 4, m.keep);
    MappableArray<int> copy = view;  // a second view of the same records
    EXPECT_TRUE(copy.is_view());
    EXPECT_EQ(copy.data(), m.bytes.data());
    MappableArray<int> own(std::vector<int>{1, 2});
    MappableArray<int> own_copy = own;
    own_copy.mutable_at(0) = 5;
    EXPECT_EQ(contents(own), (std::vector<int>{1, 2}));
    EXPECT_EQ(contents(own_copy), (std::vector<int>{5, 2}));
    MappableArray<int> moved = std::move(own);
    EXPECT_EQ(contents(moved), (std::vector<int>{1, 2}));
    EXPECT_TRUE(own.empty());  // NOLINT(bugprone-use-after-move): a moved-from array is empty
    moved.swap(copy);
    EXPECT_TRUE(moved.is_view());
    EXPECT_EQ(contents(moved), (std::vector<int>{10, 11, 12, 13}));
    EXPECT_EQ(contents(copy), (std::vector<int>{1, 2}));
    std::vector<int> taken = moved.take();
    EXPECT_EQ(taken, (std::vector<int>{10, 11, 12, 13}));
    EXPECT_TRUE(moved.empty());
    EXPECT_FALSE(moved.is_view());
}

TEST(MappableArray, AVectorOfItsOwnFollowsItsChanges) {
    MappableArray<int> a;
    for (int i = 0; i < 1000; ++i) a.push_back(i);  // reallocates many times
    EXPECT_EQ(a.size(), 1000u);
    EXPECT_EQ(a.back(), 999);
    a.resize(3);
    const MappableArray<int>& c = a;
    EXPECT_EQ(contents(c), (std::vector<int>{0, 1, 2}));
    a.assign(2, 4);
    EXPECT_EQ(contents(c), (std::vector<int>{4, 4}));
    a.clear();
    EXPECT_TRUE(c.empty());
}
