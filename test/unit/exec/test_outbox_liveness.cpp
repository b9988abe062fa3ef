// The coordinator's delivery policy (Outbox) and the role watch (RoleWatch).
#include <gtest/gtest.h>

#include "ddace/common/error.h"
#include "ddace/exec/liveness.h"
#include "ddace/exec/outbox.h"

using namespace ddace;
using namespace ddace::exec;
using K = Outbox::Kind;

TEST(Outbox, ResendsWhatIsUnansweredWithTheSameIdUntilAcknowledged) {
  Outbox box(1.0);
  box.sent(K::Decision, 7, 0.0);
  box.sent(K::Segment, 9, 0.5);
  EXPECT_TRUE(box.due(0.9).empty());
  auto d = box.due(1.0);
  ASSERT_EQ(d.size(), 1u);
  EXPECT_EQ(d[0], std::make_pair(K::Decision, 7u));
  d = box.due(1.6);  // the segment now; the decision's clock restarted at 1.0
  ASSERT_EQ(d.size(), 1u);
  EXPECT_EQ(d[0], std::make_pair(K::Segment, 9u));
  box.acknowledged(K::Decision, 7);
  EXPECT_FALSE(box.pending(K::Decision, 7));
  d = box.due(5.0);
  ASSERT_EQ(d.size(), 1u);
  EXPECT_EQ(d[0].second, 9u);
  box.acknowledged(K::Path, 9);  // another kind with the same id acknowledges nothing
  EXPECT_TRUE(box.pending(K::Segment, 9));
}

TEST(Outbox, ForgetDropsOneKindOnly) {
  Outbox box(0.5);
  box.sent(K::Path, 1, 0);
  box.sent(K::Path, 2, 0);
  box.sent(K::Segment, 3, 0);
  box.forget(K::Path);
  const auto d = box.due(1.0);
  ASSERT_EQ(d.size(), 1u);
  EXPECT_EQ(d[0].first, K::Segment);
  EXPECT_THROW(Outbox(0.0), Error);
}

TEST(RoleWatch, TheStartCheckNamesEveryRoleWithoutItsNode) {
  RoleWatch w;
  const size_t seq = w.add("sequence node", "/sequence", "subscribed to /ddace/decision_request");
  const size_t fol = w.add("follower of R1", "/path_follower", "subscribed to /robots/R1/segment", 0.5);
  w.present(fol, true);
  auto m = w.missing();
  ASSERT_EQ(m.size(), 1u);
  EXPECT_NE(m[0].find("/sequence"), std::string::npos);
  w.present(seq, true);
  EXPECT_TRUE(w.missing().empty());
}

TEST(RoleWatch, ALostNodeOrASilentHeartbeatIsNamedOnlyWhileArmed) {
  RoleWatch w;
  const size_t seq = w.add("sequence node", "/sequence", "subscribed to /ddace/decision_request");
  const size_t fol = w.add("follower of R1", "/path_follower", "subscribed to /robots/R1/segment", 0.5);
  w.present(seq, true);
  w.present(fol, true);
  EXPECT_FALSE(w.lost(100.0)) << "not armed: no run";
  w.arm(10.0);
  EXPECT_FALSE(w.lost(10.4)) << "the node has its time-out to speak after the run starts";
  w.heartbeat(fol, 10.3);
  EXPECT_FALSE(w.lost(10.7));
  auto lost = w.lost(10.9);
  ASSERT_TRUE(lost);
  EXPECT_NE(lost->find("/path_follower"), std::string::npos) << *lost;
  EXPECT_NE(lost->find("silent"), std::string::npos) << *lost;
  w.heartbeat(fol, 10.9);
  w.present(seq, false);
  lost = w.lost(11.0);
  ASSERT_TRUE(lost);
  EXPECT_NE(lost->find("/sequence"), std::string::npos) << *lost;
  EXPECT_NE(lost->find("gone"), std::string::npos) << *lost;
  EXPECT_THROW(w.add("x", "", ""), Error);
}

#include "ddace/exec/path_band.h"

TEST(PathBand, EdgesLieTwoSigmaEitherSideOfTheDirectionOfTravel) {
  PlannedPath p{{{0, 0}, {1, 0}, {2, 0}}, {0.1, 0.2, 0.0}};
  std::vector<Eigen::Vector2d> l, r;
  sigmaBandEdges(p, 2.0, l, r);
  ASSERT_EQ(l.size(), 3u);
  EXPECT_TRUE(l[0].isApprox(Eigen::Vector2d(0, 0.2)));  // +x travel: left is +y
  EXPECT_TRUE(r[1].isApprox(Eigen::Vector2d(1, -0.4)));
  EXPECT_TRUE(l[2].isApprox(Eigen::Vector2d(2, 0)));
  EXPECT_EQ(sigmaBandTriangles(p, 2.0).size(), 12u);
  EXPECT_TRUE(sigmaBandTriangles(PlannedPath{{{0, 0}}, {0.1}}, 2.0).empty());
}

#include "ddace/exec/scene.h"

TEST(CarriedObject, MovesAlongItsPathAtItsSpeedFromWhereItIs) {
  CarriedObject o({{0, 0}, {1, 0}, {1, 1}}, {0.1, 0}, 0.5);
  EXPECT_TRUE(o.position().isApprox(Eigen::Vector2d(0.1, 0)));
  EXPECT_TRUE(o.advance(1.0).isApprox(Eigen::Vector2d(0.6, 0)));
  EXPECT_TRUE(o.advance(1.0).isApprox(Eigen::Vector2d(1.0, 0.1)));  // round the corner
  EXPECT_FALSE(o.arrived());
  EXPECT_NEAR(o.progress(), 1.0 / 1.9, 1e-9);
  EXPECT_TRUE(o.advance(10.0).isApprox(Eigen::Vector2d(1, 1)));
  EXPECT_TRUE(o.arrived());
  EXPECT_THROW(CarriedObject({}, {0, 0}, 1.0), Error);
  EXPECT_THROW(CarriedObject({{0, 0}}, {0, 0}, 0.0), Error);
}
