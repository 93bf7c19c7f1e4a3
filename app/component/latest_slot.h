#pragma once
// A one-item mailbox between a producer (the DDS receive thread) and a consumer (the detector):
// put() replaces what the consumer has not taken yet, so the consumer always gets the newest item
// and nothing queues up behind a slow consumer.
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <optional>

namespace refgrasp::component {

template <class T>
class LatestSlot {
 public:
  /// Stores `item`; true when it replaced one the consumer never took (a dropped item).
  bool put(T item) {
    bool replaced;
    {
      std::lock_guard<std::mutex> lock(mu_);
      replaced = item_.has_value();
      item_ = std::move(item);
    }
    cv_.notify_one();
    return replaced;
  }
  /// Waits up to timeout_s for an item; empty on timeout or after close().
  std::optional<T> take(double timeout_s) {
    std::unique_lock<std::mutex> lock(mu_);
    cv_.wait_for(lock, std::chrono::duration<double>(timeout_s),
                 [&] { return item_.has_value() || closed_; });
    std::optional<T> out;
    if (!closed_) out.swap(item_);
    return out;
  }
  /// Wakes the consumer for good.
  void close() {
    {
      std::lock_guard<std::mutex> lock(mu_);
      closed_ = true;
    }
    cv_.notify_all();
  }

 private:
  std::mutex mu_;
  std::condition_variable cv_;
  std::optional<T> item_;
  bool closed_ = false;
};

}  // namespace refgrasp::component
