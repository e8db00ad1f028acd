#pragma once

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <mutex>
#include <optional>

namespace monoplane::app {

// A thread-safe FIFO of at most `capacity` items joining two pipeline stages. Push blocks while
// full (back-pressure for offline input) unless the queue drops the oldest item (live input);
// Pop blocks until an item arrives or the queue is closed and empty.
template <typename T>
class BoundedQueue {
 public:
  enum class WhenFull { kBlock, kDropOldest };

  explicit BoundedQueue(std::size_t capacity, WhenFull when_full = WhenFull::kBlock)
      : capacity_(capacity), when_full_(when_full) {}

  // False when the queue was closed (the item is discarded).
  bool Push(T item) {
    std::unique_lock<std::mutex> lock(mutex_);
    if (when_full_ == WhenFull::kBlock) {
      not_full_.wait(lock, [&] { return closed_ || items_.size() < capacity_; });
    }
    if (closed_) return false;  // and what is queued stays for the pops
    if (items_.size() >= capacity_) {
      items_.pop_front();
      ++dropped_;
    }
    items_.push_back(std::move(item));
    not_empty_.notify_one();
    return true;
  }

  std::optional<T> Pop() {
    std::unique_lock<std::mutex> lock(mutex_);
    not_empty_.wait(lock, [&] { return closed_ || !items_.empty(); });
    if (items_.empty()) return std::nullopt;
    T item = std::move(items_.front());
    items_.pop_front();
    not_full_.notify_one();
    return item;
  }

  // No more pushes; pops drain what is left.
  void Close() {
    std::lock_guard<std::mutex> lock(mutex_);
    closed_ = true;
    not_empty_.notify_all();
    not_full_.notify_all();
  }

  std::size_t dropped() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return dropped_;
  }

 private:
  const std::size_t capacity_;
  const WhenFull when_full_;
  mutable std::mutex mutex_;
  std::condition_variable not_empty_, not_full_;
  std::deque<T> items_;
  bool closed_ = false;
  std::size_t dropped_ = 0;
};

}  // namespace monoplane::app
