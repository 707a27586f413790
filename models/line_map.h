#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace rtsim {

// Line address -> a 32-bit value (the time-ordered cache: a line -> its newest fill in flight):
// open addressing with linear probing, an erase shifting the entries after it back, grown at
// half full. (A std::unordered_map node per fill was 3% of the accurate engine's host time.)
class LineMap {
  public:
    LineMap() { resize(64); }
    uint32_t* find(uint64_t line) {
        for (size_t i = home(line);; i = (i + 1) & mask_) {
            if (keys_[i] == line) return &values_[i];
            if (keys_[i] == kEmpty) return nullptr;
        }
    }
    void set(uint64_t line, uint32_t value) {
        if (2 * (size_ + 1) > keys_.size()) resize(2 * keys_.size());
        size_t i = home(line);
        while (keys_[i] != kEmpty && keys_[i] != line) i = (i + 1) & mask_;
        if (keys_[i] == kEmpty) {
            keys_[i] = line;
            ++size_;
        }
        values_[i] = value;
    }
    // Removes the entry whose value find() returned.
    void erase(uint32_t* value) {
        size_t hole = size_t(value - values_.data());
        for (size_t j = (hole + 1) & mask_; keys_[j] != kEmpty; j = (j + 1) & mask_) {
            // An entry may move back into the hole unless its home lies after the hole, up to it.
            const size_t h = home(keys_[j]);
            const bool stays = hole <= j ? (hole < h && h <= j) : (hole < h || h <= j);
            if (stays) continue;
            keys_[hole] = keys_[j];
            values_[hole] = values_[j];
            hole = j;
        }
        keys_[hole] = kEmpty;
        --size_;
    }

  private:
    static constexpr uint64_t kEmpty = ~uint64_t(0);
    size_t home(uint64_t line) const { return size_t((line * 0x9E3779B97F4A7C15ull) >> shift_); }
    void resize(size_t slots) {
        std::vector<uint64_t> keys = std::move(keys_);
        std::vector<uint32_t> values = std::move(values_);
        keys_.assign(slots, kEmpty);
        values_.assign(slots, 0);
        mask_ = slots - 1;
        shift_ = 64;
        for (size_t n = slots; n > 1; n >>= 1) --shift_;
        size_ = 0;
        for (size_t i = 0; i < keys.size(); ++i)
            if (keys[i] != kEmpty) set(keys[i], values[i]);
    }
    std::vector<uint64_t> keys_;
    std::vector<uint32_t> values_;
    size_t mask_ = 0, size_ = 0;
    int shift_ = 64;
};

}  // namespace rtsim
