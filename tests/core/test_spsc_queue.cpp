// Unit tests for locus::SpscQueue (core/include/locus/spsc_queue.hpp).
#include "locus/spsc_queue.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <thread>
#include <vector>

namespace {

using locus::SpscQueue;

TEST(SpscQueue, CapacityIsRoundedUpToAPowerOfTwoOfAtLeastTwo) {
  EXPECT_EQ(SpscQueue<int>(0).capacity(), 2u);
  EXPECT_EQ(SpscQueue<int>(1).capacity(), 2u);
  EXPECT_EQ(SpscQueue<int>(2).capacity(), 2u);
  EXPECT_EQ(SpscQueue<int>(3).capacity(), 4u);
  EXPECT_EQ(SpscQueue<int>(5).capacity(), 8u);
  EXPECT_EQ(SpscQueue<int>(64).capacity(), 64u);
  EXPECT_EQ(SpscQueue<int>(65).capacity(), 128u);
  EXPECT_EQ(SpscQueue<int>(1000).capacity(), 1024u);
}

TEST(SpscQueue, HoldsExactlyCapacityValuesThenRefuses) {
  SpscQueue<int> q(5);  // -> 8
  for (int i = 0; i < 8; ++i) ASSERT_TRUE(q.try_push(i)) << i;
  EXPECT_EQ(q.size_approx(), 8u);
  EXPECT_FALSE(q.try_push(99));
  EXPECT_EQ(q.size_approx(), 8u);  // a refused push changes nothing
  int v = -1;
  ASSERT_TRUE(q.try_pop(v));
  EXPECT_EQ(v, 0);
  EXPECT_TRUE(q.try_push(8));  // one slot freed
  EXPECT_FALSE(q.try_push(9));
  for (int i = 1; i <= 8; ++i) {
    ASSERT_TRUE(q.try_pop(v));
    EXPECT_EQ(v, i);
  }
  EXPECT_FALSE(q.try_pop(v));
  EXPECT_EQ(v, 8);  // a failed pop leaves `out` alone
  EXPECT_EQ(q.size_approx(), 0u);
}

TEST(SpscQueue, EmptyQueuePopsNothing) {
  SpscQueue<std::uint64_t> q(4);
  std::uint64_t v = 7;
  EXPECT_FALSE(q.try_pop(v));
  EXPECT_EQ(v, 7u);
  EXPECT_EQ(q.size_approx(), 0u);
}

TEST(SpscQueue, FifoOrderAcrossManyWraps) {
  SpscQueue<std::uint64_t> q(4);
  std::uint64_t next_push = 0, next_pop = 0;
  // Interleave pushes and pops with varying fill levels so the indices wrap the 4-slot array many times.
  for (int round = 0; round < 10000; ++round) {
    const int pushes = 1 + round % 4;
    for (int i = 0; i < pushes; ++i)
      if (q.try_push(next_push)) ++next_push;
    const int pops = 1 + (round * 7) % 4;
    for (int i = 0; i < pops; ++i) {
      std::uint64_t v;
      if (!q.try_pop(v)) break;
      ASSERT_EQ(v, next_pop);
      ++next_pop;
    }
    ASSERT_EQ(q.size_approx(), next_push - next_pop);
    ASSERT_LE(q.size_approx(), q.capacity());
  }
  EXPECT_GT(next_pop, 10000u);
}

struct Message {
  std::uint64_t seq;
  double payload[3];
  char tag;
};

TEST(SpscQueue, CopiesTriviallyCopyableStructsWhole) {
  SpscQueue<Message> q(2);
  ASSERT_TRUE(q.try_push(Message{1, {1.5, 2.5, 3.5}, 'a'}));
  ASSERT_TRUE(q.try_push(Message{2, {-1.0, 0.0, 1e300}, 'b'}));
  EXPECT_FALSE(q.try_push(Message{3, {}, 'c'}));
  Message m{};
  ASSERT_TRUE(q.try_pop(m));
  EXPECT_EQ(m.seq, 1u);
  EXPECT_EQ(m.payload[2], 3.5);
  EXPECT_EQ(m.tag, 'a');
  ASSERT_TRUE(q.try_pop(m));
  EXPECT_EQ(m.seq, 2u);
  EXPECT_EQ(m.payload[2], 1e300);
  EXPECT_EQ(m.tag, 'b');
}

TEST(SpscQueue, TwoThreadsSeeEveryValueOnceInOrder) {
  constexpr std::uint64_t kCount = 200000;
  SpscQueue<std::uint64_t> q(16);
  std::thread producer([&] {
    for (std::uint64_t i = 0; i < kCount;) {
      if (q.try_push(i * 3 + 1)) ++i;
      else std::this_thread::yield();
    }
  });
  std::uint64_t expected = 0;
  std::uint64_t bad = 0;
  while (expected < kCount) {
    std::uint64_t v;
    if (!q.try_pop(v)) {
      std::this_thread::yield();
      continue;
    }
    if (v != expected * 3 + 1) ++bad;
    ++expected;
  }
  producer.join();
  EXPECT_EQ(bad, 0u);
  EXPECT_EQ(q.size_approx(), 0u);
}

TEST(SpscQueue, SizeApproxNeverExceedsCapacityWhileBothSidesRun) {
  // size_approx() is [any]: a third thread reading it while the others run must never see a value
  // above capacity (e.g. an unsigned wrap from reading the two indices in the wrong order).
  SpscQueue<int> q(8);
  std::atomic<bool> stop{false};
  std::size_t worst = 0;
  std::thread observer([&] {
    while (!stop.load(std::memory_order_relaxed)) {
      worst = std::max(worst, q.size_approx());
      std::this_thread::yield();
    }
  });
  std::thread producer([&] {
    for (int i = 0; i < 100000;) {
      if (q.try_push(i)) ++i;
      else std::this_thread::yield();
    }
  });
  for (int got = 0; got < 100000;) {
    int v;
    if (q.try_pop(v)) ++got;
    else std::this_thread::yield();
  }
  producer.join();
  stop = true;
  observer.join();
  EXPECT_LE(worst, q.capacity());
}

}  // namespace
