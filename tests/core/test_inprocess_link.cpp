#include "locus/inprocess_link.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <mutex>
#include <vector>

#include "locus/event_bus.hpp"

namespace locus {
namespace {

TEST(TopicMatches, MqttWildcardSemantics) {
  EXPECT_TRUE(topic_matches("locus/amil/intervals", "locus/amil/intervals"));
  EXPECT_FALSE(topic_matches("locus/amil/intervals", "locus/amil/interval"));
  EXPECT_FALSE(topic_matches("locus/amil", "locus/amil/intervals"));
  EXPECT_FALSE(topic_matches("locus/amil/intervals", "locus/amil"));
  EXPECT_TRUE(topic_matches("locus/+/intervals", "locus/amil/intervals"));
  EXPECT_FALSE(topic_matches("locus/+/intervals", "locus/amil/x/intervals"));
  EXPECT_TRUE(topic_matches("locus/+", "locus/"));  // '+' matches an empty level
  EXPECT_TRUE(topic_matches("locus/#", "locus/a/b/c"));
  EXPECT_TRUE(topic_matches("locus/#", "locus"));  // '#' includes the parent level
  EXPECT_TRUE(topic_matches("#", "anything/at/all"));
  EXPECT_TRUE(topic_matches("+/+", "a/b"));
  EXPECT_FALSE(topic_matches("+/+", "a/b/c"));
  EXPECT_FALSE(topic_matches("+", "a/b"));
  EXPECT_FALSE(topic_matches("a/#/b", "a/x/b"));  // '#' must be last
}

TEST(InProcessLink, DeliversMatchingMessagesInOrderOnItsOwnThread) {
  InProcessLink link;
  std::mutex m;
  std::vector<std::string> got;
  std::atomic<bool> on_other_thread{true};
  const auto self = std::this_thread::get_id();
  link.subscribe("dev/+/intervals", [&](const LinkMessage& msg) {
    if (std::this_thread::get_id() == self) on_other_thread = false;
    std::lock_guard lock(m);
    got.push_back(msg.topic + "=" + msg.payload);
  });
  for (int i = 0; i < 100; ++i) link.publish("dev/" + std::to_string(i % 3) + "/intervals", std::to_string(i));
  link.publish("dev/x/other", "ignored");
  link.flush();
  ASSERT_EQ(got.size(), 100u);
  for (int i = 0; i < 100; ++i) EXPECT_EQ(got[i], "dev/" + std::to_string(i % 3) + "/intervals=" + std::to_string(i));
  EXPECT_TRUE(on_other_thread);
  EXPECT_EQ(link.published(), 101u);
  EXPECT_EQ(link.deliveries(), 100u);
}

TEST(InProcessLink, UnsubscribeStopsDelivery) {
  InProcessLink link;
  std::atomic<int> a{0}, b{0};
  const auto ida = link.subscribe("t", [&](const LinkMessage&) { ++a; });
  link.subscribe("t", [&](const LinkMessage&) { ++b; });
  link.publish("t", "1");
  link.flush();
  link.unsubscribe(ida);
  link.publish("t", "2");
  link.flush();
  EXPECT_EQ(a.load(), 1);
  EXPECT_EQ(b.load(), 2);
}

TEST(InProcessLink, HandlerMayPublishAndUnsubscribeItself) {
  InProcessLink link;
  std::atomic<int> pongs{0};
  std::uint64_t id = 0;
  id = link.subscribe("ping", [&](const LinkMessage&) {
    link.publish("pong", "");
    link.unsubscribe(id);  // must not deadlock
  });
  link.subscribe("pong", [&](const LinkMessage&) { ++pongs; });
  link.publish("ping", "");
  link.publish("ping", "");
  link.flush();
  EXPECT_EQ(pongs.load(), 1);
}

TEST(DispatchedLink, HandlersRunOnTheBusDispatcher) {
  InProcessLink link;
  EventBus bus;
  DispatchedLink dispatched(link, bus);
  std::vector<std::string> got;  // touched only by the thread that drains the bus (this one)
  dispatched.subscribe("x/#", [&](const LinkMessage& m) { got.push_back(m.payload); });
  dispatched.publish("x/1", "a");
  dispatched.publish("x/2", "b");
  link.flush();
  EXPECT_TRUE(got.empty());  // nothing runs until the dispatcher drains
  bus.drain();
  EXPECT_EQ(got, (std::vector<std::string>{"a", "b"}));
}

}  // namespace
}  // namespace locus
