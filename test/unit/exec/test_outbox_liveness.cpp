// The coordinator's delivery policy (Outbox) and the role watch (RoleWatch).
#include <gtest/gtest.h>

#include <optional>
#include <utility>

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
  auto m = w.missing(1.0);
  ASSERT_EQ(m.size(), 2u);
  EXPECT_NE(m[0].find("/sequence"), std::string::npos);
  // Subscribed, but its heartbeat's link may not stand yet: a run started now would
  // count the set-up as silence.
  EXPECT_NE(m[1].find("/path_follower: no heartbeat heard yet"), std::string::npos) << m[1];
  w.present(seq, true);
  w.heartbeat(fol, 1.0);
  EXPECT_TRUE(w.missing(1.2).empty());
  m = w.missing(1.6);
  ASSERT_EQ(m.size(), 1u) << "a node silent for longer than its time-out cannot start a run";
  EXPECT_NE(m[0].find("silent for 0.60 s"), std::string::npos) << m[0];
}

/// Checks `w` every `step_s` (the coordinator's liveness_check_hz) over (from_s, to_s]:
/// the first lost role's reason with the time it was found, or nullopt.
std::optional<std::pair<double, std::string>> checkOver(RoleWatch& w, double from_s, double to_s,
                                                        double step_s = 0.02) {
  for (double t = from_s + step_s; t <= to_s + 1e-9; t += step_s)
    if (auto lost = w.check(t)) return std::make_pair(t, *lost);
  return std::nullopt;
}

TEST(RoleWatch, ALostNodeOrASilentHeartbeatIsNamedOnlyWhileArmed) {
  RoleWatch w;
  const size_t seq = w.add("sequence node", "/sequence", "subscribed to /ddace/decision_request");
  const size_t fol = w.add("follower of R1", "/path_follower", "subscribed to /robots/R1/segment", 0.5);
  w.present(seq, true);
  w.present(fol, true);
  EXPECT_FALSE(w.check(100.0)) << "not armed: no run";
  w.arm(10.0);
  EXPECT_FALSE(checkOver(w, 10.0, 10.4)) << "the node has its time-out to speak after the run starts";
  w.heartbeat(fol, 10.31);
  EXPECT_FALSE(checkOver(w, 10.4, 10.8));
  const auto lost = checkOver(w, 10.8, 11.0);
  ASSERT_TRUE(lost);
  EXPECT_NEAR(lost->first, 10.82, 1e-6) << "lost at the first check after its time-out";
  EXPECT_NE(lost->second.find("/path_follower"), std::string::npos) << lost->second;
  EXPECT_NE(lost->second.find("silent"), std::string::npos) << lost->second;
  EXPECT_NE(w.longestSilences().find("follower of R1 0.51 s of 0.50 s"), std::string::npos) << w.longestSilences();
  w.heartbeat(fol, 10.9);
  w.present(seq, false);
  const auto gone = w.check(10.92);
  ASSERT_TRUE(gone);
  EXPECT_NE(gone->find("/sequence"), std::string::npos) << *gone;
  EXPECT_NE(gone->find("gone"), std::string::npos) << *gone;
  EXPECT_THROW(w.add("x", "", ""), Error);
  EXPECT_THROW(RoleWatch(0.0), Error);
}

TEST(RoleWatch, ItsOwnPauseIsNotANodesSilence) {
  // The watcher's process did not run for 0.8 s (a loaded machine): the follower's
  // heartbeats of that time may still be queued, so its clock restarts at the late check.
  RoleWatch w(0.25);
  const size_t fol = w.add("follower of R1", "/path_follower", "subscribed to /robots/R1/segment", 0.5);
  w.present(fol, true);
  w.arm(0.0);
  w.heartbeat(fol, 0.1);
  EXPECT_FALSE(checkOver(w, 0.0, 0.2));
  EXPECT_FALSE(w.check(1.0)) << "the first check after our own 0.8 s pause";
  w.heartbeat(fol, 1.01);  // what waited in the queue
  EXPECT_FALSE(checkOver(w, 1.0, 1.5));
  // A node that really stopped is still lost one time-out after the pause at the latest.
  const auto lost = checkOver(w, 1.5, 2.0);
  ASSERT_TRUE(lost);
  EXPECT_LE(lost->first, 1.01 + 0.5 + 0.02 + 1e-9);
}

TEST(RoleWatch, AProblemANodeReportsLosesItsRoleAndBlocksTheStart) {
  RoleWatch w;
  const size_t rec = w.add("recorder", "/execution_monitor", "subscribed to /coordinator/state", 1.0);
  w.present(rec, true);
  w.fault(rec, "rosbag record exited");
  w.heartbeat(rec, 0.0);
  ASSERT_EQ(w.missing(0.0).size(), 1u);
  EXPECT_NE(w.missing(0.0)[0].find("rosbag record exited"), std::string::npos) << w.missing(0.0)[0];
  w.fault(rec, "");
  EXPECT_TRUE(w.missing(0.0).empty());
  w.arm(0.0);
  w.heartbeat(rec, 0.01);
  EXPECT_FALSE(w.check(0.02));
  w.fault(rec, "rosbag record exited");
  const auto lost = w.check(0.04);
  ASSERT_TRUE(lost);
  EXPECT_NE(lost->find("/execution_monitor reports: rosbag record exited"), std::string::npos) << *lost;
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
