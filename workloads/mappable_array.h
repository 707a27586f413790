// An array that is either its own std::vector or a read-only view of a mapped cache entry
// (workloads/cache_entry.h), kept alive by a shared handle. Its records are read through const
// accessors only: writing one is mutable_at, so no read copies a view by accident. A cache hit then
// maps its records instead of copying them: on this project's machines a first touch of a fresh 4
// KB page costs about 5 us, so copying a 1080p bunny BVH's 11 MB into new vectors took 15 ms of a
// 135 ms sampled run, against 4-5 ms to map and checksum it. Reading is the same either way;
// anything that changes the array first copies a view into a vector of its own (copy on write), so
// code that builds or edits a tree never sees the difference.
#pragma once

#include <algorithm>
#include <cstddef>
#include <memory>
#include <stdexcept>
#include <type_traits>
#include <utility>
#include <vector>

namespace rtsim {

template <class T>
class MappableArray {
    static_assert(std::is_trivially_copyable_v<T>);

  public:
    using value_type = T;
    using size_type = size_t;
    using iterator = T*;
    using const_iterator = const T*;

    MappableArray() = default;
    MappableArray(std::vector<T> v) : own_(std::move(v)) { point_at_own(); }
    MappableArray(const MappableArray& o) : own_(o.own_), keep_(o.keep_) {
        if (keep_) {
            data_ = o.data_;
            size_ = o.size_;
        } else {
            point_at_own();
        }
    }
    MappableArray(MappableArray&& o) noexcept : own_(std::move(o.own_)), keep_(std::move(o.keep_)) {
        if (keep_) {
            data_ = o.data_;
            size_ = o.size_;
        } else {
            point_at_own();
        }
        o.reset_view();
    }
    MappableArray& operator=(MappableArray o) noexcept {
        swap(o);
        return *this;
    }
    MappableArray& operator=(std::vector<T> v) {
        keep_.reset();
        own_ = std::move(v);
        point_at_own();
        return *this;
    }
    void swap(MappableArray& o) noexcept {
        own_.swap(o.own_);
        keep_.swap(o.keep_);
        std::swap(data_, o.data_);
        std::swap(size_, o.size_);
        if (!keep_) point_at_own();
        if (!o.keep_) o.point_at_own();
    }

    // A view of `n` records at `data`, valid while `keep` lives.
    void view(const T* data, size_t n, std::shared_ptr<const void> keep) {
        own_.clear();
        own_.shrink_to_fit();
        keep_ = std::move(keep);
        data_ = data;
        size_ = n;
    }
    // True while this is a view of mapped records (not a vector of its own).
    bool is_view() const { return bool(keep_); }

    // Reading: the same whatever holds the records.
    size_t size() const { return size_; }
    bool empty() const { return size_ == 0; }
    const T* data() const { return data_; }
    const T& operator[](size_t i) const { return data_[i]; }
    const T& at(size_t i) const {
        if (i >= size_) throw std::out_of_range("MappableArray::at");
        return data_[i];
    }
    const T& front() const { return data_[0]; }
    const T& back() const { return data_[size_ - 1]; }
    const T* begin() const { return data_; }
    const T* end() const { return data_ + size_; }

    friend bool operator==(const MappableArray& a, const MappableArray& b) {
        return std::equal(a.begin(), a.end(), b.begin(), b.end());
    }
    friend bool operator!=(const MappableArray& a, const MappableArray& b) { return !(a == b); }

    // Changing: on a vector of its own (a view is copied into one first).

    // The records as a vector of their own, moved out (this array is left empty).
    std::vector<T> take() {
        std::vector<T> v = std::move(sync());
        reset_view();
        return v;
    }
    // A record to change (named, not operator[], so a read never copies a view by accident).
    T& mutable_at(size_t i) { return sync()[i]; }
    void resize(size_t n) {
        mutate([&](std::vector<T>& v) { v.resize(n); });
    }
    void resize(size_t n, const T& x) {
        mutate([&](std::vector<T>& v) { v.resize(n, x); });
    }
    void assign(size_t n, const T& x) {
        mutate([&](std::vector<T>& v) { v.assign(n, x); });
    }
    void reserve(size_t n) {
        mutate([&](std::vector<T>& v) { v.reserve(n); });
    }
    void clear() {
        mutate([&](std::vector<T>& v) { v.clear(); });
    }
    void push_back(const T& x) {
        mutate([&](std::vector<T>& v) { v.push_back(x); });
    }
    template <class... A>
    T& emplace_back(A&&... a) {
        T* r = nullptr;
        mutate([&](std::vector<T>& v) { r = &v.emplace_back(std::forward<A>(a)...); });
        return *r;
    }

  private:
    void point_at_own() {
        data_ = own_.data();
        size_ = own_.size();
    }
    void reset_view() {
        keep_.reset();
        own_.clear();
        point_at_own();
    }
    // The vector of its own, with the cached pointer brought up to date.
    std::vector<T>& sync() {
        if (keep_) {
            own_.assign(data_, data_ + size_);
            keep_.reset();
        }
        point_at_own();
        return own_;
    }
    template <class F>
    void mutate(F&& f) {
        f(sync());
        point_at_own();
    }

    std::vector<T> own_;
    std::shared_ptr<const void> keep_;  // the mapping a view reads (empty: own_ holds the records)
    const T* data_ = nullptr;
    size_t size_ = 0;
};

}  // namespace rtsim
