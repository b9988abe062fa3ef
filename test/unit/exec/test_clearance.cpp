// The run's clearance measurement: the closest approach, collisions counted once per
// contact, a load placed on its carrier not measured.
#include <gtest/gtest.h>

#include <cmath>

#include "ddace/common/error.h"
#include "ddace/exec/clearance.h"

using namespace ddace::exec;
using Eigen::Vector2d;

TEST(ClearanceMeter, ClosestApproachAndOneCollisionPerContact) {
  ClearanceMeter m({0.02, 0.02, 0.0});  // two bodies and a goal
  const Vector2d goal(0.05, 0.0);       // flat: never measured, even when driven over
  // R2 comes at R1 from 0.2 m, overlaps by 5 mm twice (apart in between), stops at 1 cm;
  // noise at contact (a 4 mm overlap and 1 mm apart in between) is one contact.
  const std::vector<double> xs = {0.2, 0.1, 0.035, 0.036, 0.041, 0.036, 0.05, 0.035, 0.05, 0.05};
  for (size_t k = 0; k < xs.size(); ++k) m.update(k * 0.1, {{0, 0}, {xs[k], 0}, goal});
  EXPECT_NEAR(m.closest().clearance_m, -0.005, 1e-12);
  EXPECT_EQ(m.closest().a, 0);
  EXPECT_EQ(m.closest().b, 1);
  EXPECT_NEAR(m.closest().time_s, 0.2, 1e-12);
  ASSERT_EQ(m.collisions().size(), 2u);
  EXPECT_NEAR(m.collisions()[0].time_s, 0.2, 1e-12);
  EXPECT_NEAR(m.collisions()[1].time_s, 0.7, 1e-12);
}

TEST(ClearanceMeter, TrackingNoiseAtContactIsNoCollision) {
  ClearanceMeter m({0.02, 0.02}, 0.002);
  m.update(0, {{0, 0}, {0.1, 0}});
  m.update(1, {{0, 0}, {0.039, 0}});  // 1 mm overlap: touching, within the noise
  EXPECT_TRUE(m.collisions().empty());
  EXPECT_NEAR(m.closest().clearance_m, -0.001, 1e-12);
}

TEST(ClearanceMeter, ALoadOnItsCarrierIsNotMeasured) {
  ClearanceMeter m({0.02, 0.02});
  m.update(0, {{0, 0}, {0, 0}});
  m.update(1, {{0.1, 0}, {0.1, 0.001}});
  EXPECT_TRUE(m.collisions().empty());
  EXPECT_EQ(m.loadedPairs().size(), 1u);
  EXPECT_EQ(m.closest().a, -1);
}

// Two bodies touching when first seen read overlapping by the tracking noise (a box placed
// at its carrier, 3 mm): they touch, not one on the other. No collision while they stay in
// touch; parted and driven into each other again, they collide (before: never measured).
TEST(ClearanceMeter, BodiesTouchingWhenFirstSeenCollideOnceTheyPartedAndMetAgain) {
  ClearanceMeter m({0.02, 0.02}, 0.002);
  m.update(0, {{0, 0}, {0.037, 0}});
  m.update(1, {{0, 0}, {0.036, 0}});
  EXPECT_TRUE(m.collisions().empty());
  EXPECT_TRUE(m.loadedPairs().empty());
  m.update(2, {{0, 0}, {0.1, 0}});
  m.update(3, {{0, 0}, {0.035, 0}});
  ASSERT_EQ(m.collisions().size(), 1u);
  EXPECT_NEAR(m.collisions()[0].time_s, 3, 1e-12);
}

TEST(ClearanceMeter, UnknownPositionsWaitUntilSeen) {
  ClearanceMeter m({0.02, 0.02});
  m.update(0, {{0, 0}, Vector2d::Constant(NAN)});
  EXPECT_EQ(m.closest().a, -1);
  m.update(1, {{0, 0}, {0.1, 0}});
  EXPECT_NEAR(m.closest().clearance_m, 0.06, 1e-12);
}

// The run report measures what `ddace eval` measures: a carrier and the load riding in
// front of it touch by design (the run report showed -0.33 cm for them), a robot ending at
// its target or at the robot already on the goal touches it -- none of that is a collision
// or the closest approach; two robots that only pass each other are.
TEST(ClearanceMeter, PairsAllowedToTouchInTheStepAreNotMeasured) {
  using ddace::task::EntityKind;
  ddace::task::TaskSpec spec;
  for (const auto& [name, kind] : std::vector<std::pair<std::string, EntityKind>>{{"R1", EntityKind::Robot},
                                                                                  {"B", EntityKind::Object},
                                                                                  {"R2", EntityKind::Robot},
                                                                                  {"R3", EntityKind::Robot},
                                                                                  {"G1", EntityKind::Goal}})
    spec.entities.push_back({name, kind, ""});
  const double r = 0.022;
  const std::vector<double> radii{r, r, r, r, 0};
  // R1 carries B onto G1; R3, sent to G1 too, ends at contact with R2, which stands still.
  const std::vector<ddace::task::Token> step{{0, "move", 4}, {1, "move", 4}, {3, "move", 4}};
  const Vector2d g1(0.5, 0.3), r2(0.3, 0.6), r3_end = r2 + Vector2d(2 * r, 0);
  const std::vector<Vector2d> ends{g1 - Vector2d(2 * r, 0), g1, r2, r3_end, g1};
  const std::vector<Vector2d> starts{{0.2, 0.3}, {0.2 + 2 * r, 0.3}, r2, r2 + Vector2d(0.2, 0), g1};
  const AllowedContacts allowed(spec, step, starts, ends, {true, true, false, true, false}, radii, 0.01);
  EXPECT_TRUE(allowed.allowed(0, 1, {0, 0}, {1, 1})) << "a carrier and the load riding with it, wherever they are";
  EXPECT_TRUE(allowed.allowed(3, 2, r3_end, r2)) << "R3 at its end against R2";
  EXPECT_FALSE(allowed.allowed(3, 2, r3_end, r2 + Vector2d(0, 0.1))) << "R2 elsewhere than R3's end point";
  EXPECT_FALSE(allowed.allowed(0, 3, {0, 0}, {0.044, 0}));

  ClearanceMeter m(radii);
  // The load rides 3.3 mm into its carrier; R3 touches R2 at its end, then drives off.
  m.update(0, {{0.1, 0.3}, {0.2, 0.3}, r2, r2 + Vector2d(0.2, 0), g1}, allowed);
  m.update(1, {{0.2, 0.3}, {0.2 + 2 * r - 0.0033, 0.3}, r2, r3_end - Vector2d(0.001, 0), g1}, allowed);
  EXPECT_TRUE(m.collisions().empty());
  EXPECT_GT(m.closest().clearance_m, 0.05) << m.closest().a << "-" << m.closest().b;
  // Without the step's allowed contacts both are measured, and the load's overlap is a collision.
  ClearanceMeter plain(radii);
  plain.update(0, {{0.1, 0.3}, {0.2, 0.3}, r2, r2 + Vector2d(0.2, 0), g1});
  plain.update(1, {{0.2, 0.3}, {0.2 + 2 * r - 0.0033, 0.3}, r2, r3_end - Vector2d(0.001, 0), g1});
  EXPECT_NEAR(plain.closest().clearance_m, -0.0033, 1e-9);
  // The carrier driving into R2 on its way is a collision and the closest approach.
  const Vector2d r1 = r2 - Vector2d(0, 0.03);
  m.update(2, {r1, r1 - Vector2d(2 * r - 0.0033, 0), r2, r3_end - Vector2d(0.001, 0), g1}, allowed);
  ASSERT_EQ(m.collisions().size(), 1u);
  EXPECT_EQ(m.collisions()[0].a, 0);
  EXPECT_EQ(m.collisions()[0].b, 2);
  EXPECT_NEAR(m.closest().clearance_m, 0.03 - 2 * r, 1e-9);
}

// The step after: nothing is allowed any more. R3, which ended against R2, resting there
// (noise within the tolerance) is no collision; pushing into R2 is one; and once it drove
// off, the pair is measured again.
TEST(ClearanceMeter, AContactAllowedInAStepIsACollisionWhenLaterPushedIn) {
  using ddace::task::EntityKind;
  ddace::task::TaskSpec spec;
  spec.entities.push_back({"R2", EntityKind::Robot, ""});
  spec.entities.push_back({"R3", EntityKind::Robot, ""});
  const double r = 0.022;
  const std::vector<double> radii{r, r};
  const Vector2d r2(0.3, 0.6), r3_end = r2 + Vector2d(2 * r, 0);
  const std::vector<ddace::task::Token> step{{1, "move", 0}};  // R3 to R2
  const AllowedContacts to_r2(spec, step, {r2, r2 + Vector2d(0.3, 0)}, {r2, r3_end}, {false, true}, radii, 0.01);
  ClearanceMeter m(radii);
  m.update(0, {r2, r2 + Vector2d(0.3, 0)}, to_r2);
  m.update(1, {r2, r3_end - Vector2d(0.0015, 0)}, to_r2);  // ended at contact
  EXPECT_TRUE(m.collisions().empty());
  m.update(2, {r2, r3_end - Vector2d(0.001, 0)});  // the next step: still resting there
  EXPECT_TRUE(m.collisions().empty());
  EXPECT_GT(m.closest().clearance_m, 0.2);
  m.update(3, {r2, r3_end - Vector2d(0.006, 0)});  // shoves into R2
  ASSERT_EQ(m.collisions().size(), 1u);
  EXPECT_NEAR(m.collisions()[0].time_s, 3, 1e-12);
  EXPECT_NEAR(m.closest().clearance_m, -0.006, 1e-9);

  ClearanceMeter off(radii);
  off.update(0, {r2, r2 + Vector2d(0.3, 0)}, to_r2);
  off.update(1, {r2, r3_end - Vector2d(0.0015, 0)}, to_r2);
  off.update(2, {r2, r3_end + Vector2d(0.03, 0)});  // drives off
  off.update(3, {r2, r3_end + Vector2d(0.01, 0)});  // and comes back near: measured
  EXPECT_TRUE(off.collisions().empty());
  EXPECT_NEAR(off.closest().clearance_m, 0.01, 1e-9);
}

// A load passed from afar moves on its own path: its carrier hitting it from the side is a
// collision; a load riding with its carrier (within task::togetherDistance at the start)
// touches it by design.
TEST(ClearanceMeter, ACarrierAndALoadFromAfarKeepApart) {
  using ddace::task::EntityKind;
  ddace::task::TaskSpec spec;
  spec.entities.push_back({"R1", EntityKind::Robot, ""});
  spec.entities.push_back({"B", EntityKind::Object, ""});
  spec.entities.push_back({"G1", EntityKind::Goal, ""});
  const double r = 0.022;
  const std::vector<double> radii{r, r, 0};
  const std::vector<ddace::task::Token> step{{0, "move", 2}, {1, "move", 2}};
  const Vector2d g1(0.5, 0.3);
  const std::vector<Vector2d> ends{g1 - Vector2d(2 * r, 0), g1, g1};
  const AllowedContacts afar(spec, step, {{0.1, 0.3}, {0.5, 0.0}, g1}, ends, {true, true, false}, radii, 0.01);
  EXPECT_FALSE(afar.allowed(0, 1, {0.4, 0.2}, {0.4 + 2 * r - 0.005, 0.2}));
  ClearanceMeter m(radii);
  m.update(0, {{0.1, 0.3}, {0.5, 0.0}, g1}, afar);
  m.update(1, {{0.4, 0.2}, {0.4 + 2 * r - 0.005, 0.2}, g1}, afar);  // hit from the side on the way
  ASSERT_EQ(m.collisions().size(), 1u);

  const AllowedContacts rides(spec, step, {{0.1, 0.3}, {0.1 + 2 * r, 0.3}, g1}, ends, {true, true, false}, radii, 0.01);
  EXPECT_TRUE(rides.allowed(0, 1, {0.4, 0.2}, {0.4 + 2 * r - 0.005, 0.2}));
}

// The execution monitor's contacts of the running step, as its segments arrive: a token of
// another entity is refused naming both, a new step forgets the last one's exemptions,
// and contacts that cannot be decided allow nothing (no stale exemption stays).
TEST(StepContacts, RefuseAnotherEntitysTokenAndKeepNoStaleExemption) {
  using ddace::task::EntityKind;
  ddace::task::TaskSpec spec;
  for (const char* name : {"R1", "R2", "R3"}) spec.entities.push_back({name, EntityKind::Robot, ""});
  const double r = 0.022;
  const Vector2d r2(0.3, 0.6), r3_end = r2 + Vector2d(2 * r, 0);
  const std::vector<Vector2d> at{{0.1, 0.1}, r2, r2 + Vector2d(0.3, 0)};
  StepContacts sc(spec, {r, r, r}, 0.01);
  sc.note(0, 2, {2, "move", 1}, r3_end, at);  // R3 to R2
  EXPECT_TRUE(sc.allowed().allowed(2, 1, r3_end, r2));
  try {
    sc.note(0, 0, {2, "move", 0}, {0.2, 0.1}, at);  // R1's segment with R3's token
    FAIL() << "another entity's token was counted";
  } catch (const ddace::Error& e) {
    EXPECT_NE(std::string(e.what()).find("R1"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("R3"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(sc.allowed().allowed(2, 1, r3_end, r2)) << "the step's own contacts stay";
  EXPECT_FALSE(sc.allowed().allowed(2, 0, r3_end, {0.2, 0.1}));

  sc.note(1, 0, {0, "move", 1}, {0.2, 0.1}, at);  // the next step: R1 to R2
  EXPECT_FALSE(sc.allowed().allowed(2, 1, r3_end, r2)) << "the last step's exemption stays";
  EXPECT_TRUE(sc.allowed().allowed(0, 1, {0.2, 0.1}, r2));
  EXPECT_THROW(sc.note(1, 2, {2, "move", 7}, r3_end, at), ddace::Error);  // a target outside the task
  EXPECT_FALSE(sc.allowed().allowed(0, 1, {0.2, 0.1}, r2)) << "undecided: every contact counts";
  // The bad segment is not kept: the step's next one is worked out with the good ones.
  sc.note(1, 1, {1, "move", 2}, at[2] - Vector2d(2 * r, 0), at);  // R2 to R3
  EXPECT_TRUE(sc.allowed().allowed(0, 1, {0.2, 0.1}, r2));
  EXPECT_TRUE(sc.allowed().allowed(1, 2, at[2] - Vector2d(2 * r, 0), at[2]));
}
