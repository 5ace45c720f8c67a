// docs/writing-a-localizer.md, run: the `nearest` skeleton extracted from the doc (plugins/nearest/)
// and plugins/amil copied by the doc's recipe (plugins/amilcopy/) are built into this binary beside
// every built-in plugin, registered the way plugins/CMakeLists.txt registers built-ins, and run.
#include <gtest/gtest.h>

#include <memory>
#include <string>
#include <variant>
#include <vector>

#include "amilcopy/amilcopy.hpp"
#include "locus/inprocess_link.hpp"
#include "locus/registry.hpp"
#include "nearest/messages.hpp"
#include "nearest/nearest.hpp"
#include "nearest/solver.hpp"
#include "support/test_host.hpp"

namespace locus {
namespace {

namespace nearest = plugins::nearest;

struct Collect final : Publisher {
  void publish(const Event& e) override { events.push_back(e); }
  std::vector<Event> events;
};

/// The built-ins, then the two plugins of the doc, as builtin_plugins.cpp would list them.
void register_with_doc_plugins(Registry& r) {
  register_builtins(r);
  r.add_plugin(nearest::descriptor());
  r.add_plugin(plugins::amilcopy::descriptor());
}

TEST(DocWritingALocalizer, SkeletonAndAmilCopyRegisterBesideTheBuiltIns) {
  Registry r;
  register_with_doc_plugins(r);
  for (const char* name : {"amil", "amilcopy", "nearest", "chirp"}) ASSERT_NE(r.find_plugin(name), nullptr) << name;
  EXPECT_EQ(r.find_plugin("nearest")->kind, LOCUS_PLUGIN_LOCALIZER);
  EXPECT_EQ(r.find_plugin("amilcopy")->kind, LOCUS_PLUGIN_LOCALIZER);
  // The copy is AMIL under another name: same parameters, its own link topic.
  const ParamSchema& a = *r.find_plugin("amil")->schema();
  const ParamSchema& c = *r.find_plugin("amilcopy")->schema();
  ASSERT_EQ(a.size(), c.size());
  for (std::size_t i = 0; i < a.size(); ++i) EXPECT_EQ(a[i].key, c[i].key);
  EXPECT_EQ(Params::defaults(c).get_string("topic"), "amilcopy");
  // Both run side by side: their internals do not clash.
  test::TestHost host;
  for (const char* name : {"amil", "amilcopy"}) {
    std::unique_ptr<Localizer> loc = r.create_localizer(name);
    HostContext ctx = host.context(name, "L1");
    Params p = Params::defaults(*r.find_plugin(name)->schema());
    p.set("role", std::string("listener"));
    EXPECT_NO_THROW(loc->configure(p, ctx)) << name;
  }
}

TEST(DocWritingALocalizer, MessagesRoundTripAndRefuseMalformedText) {
  const nearest::Heard h{"B", 17.25, {4.0, -1.5, 0.125}};
  const auto back = nearest::decode(nearest::encode(h));
  ASSERT_TRUE(back.has_value());
  EXPECT_EQ(back->device, "B");
  EXPECT_EQ(back->snr_db, 17.25);
  EXPECT_EQ(back->anchor_m, h.anchor_m);
  for (const char* bad : {"", "B 17", "B x 1 2 3", "B 1 2 3 4 extra", "B 1 nan 2 3"})
    EXPECT_FALSE(nearest::decode(bad).has_value()) << bad;
  EXPECT_FALSE(nearest::loudest({}).has_value());
  EXPECT_EQ(nearest::loudest({{"A", 3, {}}, {"B", 9, {}}, {"C", 9, {}}})->device, "B");
}

TEST(DocWritingALocalizer, NearestPlacesTheTagAtTheLoudestAnchorOverALink) {
  Registry r;
  register_with_doc_plugins(r);
  test::TestHost host;
  InProcessLink link;
  struct Node {
    std::string id;
    DeviceGeometry geometry;
    std::unique_ptr<Localizer> loc;
  };
  std::vector<Node> nodes(3);
  nodes[0].id = "A";
  nodes[0].geometry.has_anchor = true;
  nodes[0].geometry.anchor_m = {0.0, 0.0, 1.0};
  nodes[1].id = "B";
  nodes[1].geometry.has_anchor = true;
  nodes[1].geometry.anchor_m = {4.0, 2.0, 1.0};
  nodes[2].id = "C";  // no anchor: hears loudest, but cannot place anything
  for (Node& n : nodes) {
    n.loc = r.create_localizer("nearest");
    const std::string instance = n.id == "A" ? "nearest_a" : "nearest_x";
    HostContext ctx{host.log, host.clock, host.fft, link, instance, n.id, n.id == "C" ? nullptr : &n.geometry, nullptr};
    Params p = Params::defaults(nearest::schema());
    p.set("reporter", std::string("A"));
    n.loc->configure(p, ctx);
    EXPECT_EQ(n.loc->subscriptions(), std::vector<EventType>{EventType::AudioDetection});
  }
  Collect out;
  auto heard = [&](Node& n, float snr_db) {
    AudioDetection d;
    d.device.assign(n.id);
    d.snr_db = snr_db;
    n.loc->on_event(d, out);
  };
  heard(nodes[0], 10.0f);
  heard(nodes[1], 20.0f);
  heard(nodes[1], 15.0f);  // quieter than B's best: nothing new
  heard(nodes[2], 30.0f);
  link.flush();
  EXPECT_EQ(link.published(), 2u);
  for (Node& n : nodes) n.loc->finish(out);
  ASSERT_EQ(out.events.size(), 1u);  // only the reporter publishes
  const auto* e = std::get_if<Estimate>(&out.events[0]);
  ASSERT_NE(e, nullptr);
  EXPECT_EQ(e->plugin.view(), "nearest_a");
  EXPECT_EQ(e->target.view(), "tag");
  EXPECT_EQ(e->frame.view(), "world");
  EXPECT_EQ(e->dims, 3);
  EXPECT_EQ(e->position_m, (std::array<double, 3>{4.0, 2.0, 1.0}));
  for (Node& n : nodes) n.loc.reset();  // unsubscribes before the link goes
}

}  // namespace
}  // namespace locus
