// Motion primitives by role: where the scene decides who does what, a motion class is keyed
// by the step its motions stand in when that predicts held-out demonstrations better than the
// names; a fixed order keeps the names (they are the role).
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <map>
#include <regex>

#include "ddace/common/error.h"
#include "ddace/common/file.h"
#include "ddace/eval/frechet.h"
#include "ddace/gp/canonical.h"
#include "ddace/gp/primitives.h"
#include "ddace/task/end_point.h"

#include "../common/generated_task.h"
#include "../common/role_tasks.h"

using namespace ddace;
using Eigen::Vector2d;

namespace {

constexpr const char* kRobotToRobot = "robot:hamster/move/robot:hamster";

/// The lateral offset at mid-progress of `path` in its own canonical frame (+ left of the
/// start-to-end line), in start-to-end distances.
double bend(const std::vector<Vector2d>& path) {
  const gp::CanonicalFrame frame(path.front(), path.back());
  return frame.toCanonical(gp::resampleByProgress(path, 101))[50].y();
}

/// Mean normalised FD per key over the motions of `test`, generated with their steps (roles)
/// or without (names).
std::map<std::string, double> frechetByKey(const gp::PrimitiveLibrary& lib, const task::TaskDir& test, bool roles) {
  std::map<std::string, std::pair<double, int>> sum;
  for (const auto& demo : test.demos)
    for (const auto& seg : demo.segments) {
      if (!seg.token.isMotion()) continue;
      const auto truth = demo.segmentPath(seg);
      const gp::GeneratedPath g =
          lib.generate(seg.token, truth.front(), task::segmentEndPoint(test.spec, lib.endPoints(), demo, seg), 100,
                       roles ? seg.step : -1);
      auto& [total, count] = sum[task::tokenKey(seg.token, test.spec)];
      total += eval::normalisedFrechet(g.points, truth);
      ++count;
    }
  std::map<std::string, double> mean;
  for (const auto& [key, s] : sum) mean[key] = s.first / s.second;
  return mean;
}

double worst(const std::map<std::string, double>& fd) {
  double w = 0;
  for (const auto& entry : fd) w = std::max(w, entry.second);
  return w;
}

const gp::PrimitiveLibrary& lineUpLibrary() {
  static const gp::PrimitiveLibrary lib = gp::PrimitiveLibrary::fit(test::lineUp(12, 1));
  return lib;
}

}  // namespace

TEST(Roles, ALineUpsPathBendsTheWayItsRoleWasDemonstrated) {
  const gp::PrimitiveLibrary& lib = lineUpLibrary();
  const std::vector<std::string> classes = lib.roleClasses();
  EXPECT_NE(std::find(classes.begin(), classes.end(), kRobotToRobot), classes.end());
  const task::TaskDir test = test::lineUp(10, 2);
  int checked = 0;
  for (const auto& demo : test.demos)
    for (const auto& seg : demo.segments) {
      if (!seg.token.isMotion() || test.spec.entities[seg.token.target].kind != task::EntityKind::Robot) continue;
      const auto truth = demo.segmentPath(seg);
      const gp::GeneratedPath g = lib.generate(
          seg.token, truth.front(), task::segmentEndPoint(test.spec, lib.endPoints(), demo, seg), 100, seg.step);
      // The second robot arcs right toward the head, the third left toward the second,
      // whatever their names.
      const std::string what = task::tokenKey(seg.token, test.spec) + " in step " + std::to_string(seg.step + 1);
      EXPECT_GT(bend(truth) * bend(g.points), 0.0)
          << what << ": demonstrated " << bend(truth) << ", generated " << bend(g.points);
      EXPECT_GT(std::abs(bend(g.points)), 0.15) << what;
      EXPECT_EQ(g.source_key, gp::roleKey(kRobotToRobot, seg.step)) << what;
      ++checked;
    }
  EXPECT_EQ(checked, 20);
  const auto by_role = frechetByKey(lib, test, true), by_name = frechetByKey(lib, test, false);
  for (const auto& [key, fd] : by_role)
    std::cout << key << ": FD by role " << fd << ", by name " << by_name.at(key) << "\n";
  EXPECT_LT(worst(by_role), 0.05);
  EXPECT_GT(worst(by_name), 0.1) << "the names mix the roles' shapes";
}

TEST(Roles, ANewRobotGetsThePathOfItsRole) {
  const gp::PrimitiveLibrary bound = lineUpLibrary().boundTo(test::lineUp(1, 3, 6).spec);
  // R6 joining R5 in step 6: the role of a robot joining one that joined another, the
  // nearest demonstrated step's (3).
  const gp::GeneratedPath joining = bound.generate("R6:move:R5", {0.2, 0.2}, {0.6, 0.2}, 100, 5);
  EXPECT_EQ(joining.source_key, gp::roleKey(kRobotToRobot, 2));
  EXPECT_TRUE(joining.fell_back) << "step 6 was never demonstrated";
  EXPECT_GT(bend(joining.points), 0.15) << "arcs left, as the third robot did";
  const gp::GeneratedPath second = bound.generate("R6:move:R5", {0.2, 0.2}, {0.6, 0.2}, 100, 1);
  EXPECT_LT(bend(second.points), -0.15) << "arcs right, as the second robot did";
  EXPECT_FALSE(second.fell_back);
  // Toward the goal: every robot drove straight (one role, pooled over the names).
  const gp::GeneratedPath head = bound.generate("R6:move:G1", {0.2, 0.2}, {0.6, 0.2}, 100, 0);
  EXPECT_FALSE(head.fell_back);
  EXPECT_LT(std::abs(bend(head.points)), 0.05);
}

TEST(Roles, TwoRobotsToOneGoalEachGetsItsOwnShape) {
  const gp::PrimitiveLibrary lib = gp::PrimitiveLibrary::fit(test::twoToOneGoal(12, 1));
  EXPECT_EQ(lib.roleClasses(), std::vector<std::string>{"robot:hamster/move/goal"});
  const task::TaskDir test = test::twoToOneGoal(10, 2);
  // The shape alone: toward where each motion truly ended (the end point's own error, the
  // second robot stopping at the first, is the end-point rule's, task/end_point.h).
  double role_fd = 0, name_fd = 0;
  int motions = 0;
  for (const auto& demo : test.demos)
    for (const auto& seg : demo.segments) {
      const auto truth = demo.segmentPath(seg);
      const gp::GeneratedPath by_role = lib.generate(seg.token, truth.front(), truth.back(), 100, seg.step),
                              by_name = lib.generate(seg.token, truth.front(), truth.back());
      if (seg.step == 1) {
        EXPECT_GT(bend(by_role.points), 0.15) << "the second robot arcs left";
      } else {
        EXPECT_LT(std::abs(bend(by_role.points)), 0.05) << "the first drives straight";
      }
      role_fd += eval::normalisedFrechet(by_role.points, truth);
      name_fd += eval::normalisedFrechet(by_name.points, truth);
      ++motions;
    }
  EXPECT_EQ(motions, 20);
  std::cout << "FD toward the true ends: by role " << role_fd / motions << ", by name " << name_fd / motions << "\n";
  EXPECT_LT(role_fd / motions, 0.02);
  EXPECT_GT(name_fd / motions, 0.1);
  // Toward the rule's end points: each role's own (the first on G1, the second at it).
  const auto by_role = frechetByKey(lib, test, true), by_name = frechetByKey(lib, test, false);
  for (const auto& [key, fd] : by_role)
    std::cout << key << ": FD by role " << fd << ", by name " << by_name.at(key) << "\n";
  EXPECT_LT(worst(by_role), 0.02);
  EXPECT_GT(worst(by_name), 0.1);
}

TEST(Roles, EachRoleEndsWhereItsRoleStopped) {
  // The first robot stops on G1, the second at contact with the first, whoever they are: by
  // name, R1:move:G1 holds both ends and its median lies between them.
  const gp::PrimitiveLibrary lib = gp::PrimitiveLibrary::fit(test::twoToOneGoal(12, 1));
  const task::EndPointModel& ends = lib.endPoints();
  ASSERT_EQ(ends.by_role.count("robot->goal"), 1u);
  EXPECT_EQ(ends.by_role.at("robot->goal").size(), 2u) << "one end per step";
  const task::TaskDir test = test::twoToOneGoal(10, 2);
  double role_error = 0, name_error = 0;
  int motions = 0;
  for (const auto& demo : test.demos)
    for (const auto& seg : demo.segments) {
      const Vector2d stopped = demo.segmentPath(seg).back();
      const std::vector<task::Token>& step = demo.steps[static_cast<size_t>(seg.step)].tokens;
      const auto& decided = demo.snapshots[static_cast<size_t>(seg.step)].positions;
      const size_t i = static_cast<size_t>(std::find(step.begin(), step.end(), seg.token) - step.begin());
      const Vector2d by_role = task::endPoint(test.spec, ends, step, i, decided, seg.step),
                     by_name = task::endPoint(test.spec, ends, step, i, decided);
      EXPECT_EQ(by_role, task::segmentEndPoint(test.spec, ends, demo, seg)) << "a segment's end is its role's";
      EXPECT_LT((by_role - stopped).norm(), 0.005) << "step " << seg.step + 1;
      role_error += (by_role - stopped).norm(), name_error += (by_name - stopped).norm();
      ++motions;
    }
  EXPECT_EQ(motions, 20);
  std::cout << "mean end error: by role " << role_error / motions << " m, by name " << name_error / motions << " m\n";
  EXPECT_GT(name_error / motions, 0.01);
  // A step never demonstrated takes the nearest demonstrated one's end.
  const std::vector<task::Token> third = {{1, "move", 2}};
  const std::vector<Vector2d> at = {{0.5, 0.5}, {0.2, 0.5}, {0.5, 0.5}};
  EXPECT_EQ(task::endPoint(test.spec, ends, third, 0, at, 5), task::endPoint(test.spec, ends, third, 0, at, 1));
  // The library file keeps them; a library of the format before them reads without them (its
  // ends by name, as it was trained), and one that holds them anyway is refused by line.
  const std::string text = lib.text();
  const gp::PrimitiveLibrary back = gp::PrimitiveLibrary::parse(text, "ends.yaml");
  ASSERT_EQ(back.endPoints().by_role.size(), 1u);
  for (const auto& [k, e] : ends.by_role.at("robot->goal")) {
    EXPECT_EQ(back.endPoints().by_role.at("robot->goal").at(k).offset, e.offset);
    EXPECT_EQ(back.endPoints().by_role.at("robot->goal").at(k).segments, e.segments);
  }
  const std::string v4 = std::regex_replace(text, std::regex("ddace-primitives/5"), "ddace-primitives/4");
  const std::string v4_clean = std::regex_replace(v4, std::regex("  by_role:[^\\n]*\\n(    - [^\\n]*\\n)*"), "");
  ASSERT_NE(v4_clean, v4);
  EXPECT_TRUE(gp::PrimitiveLibrary::parse(v4_clean, "ends.yaml").endPoints().by_role.empty());
  try {
    gp::PrimitiveLibrary::parse(v4, "ends.yaml");
    ADD_FAILURE() << "a /4 library with ends by role was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("by_role"), std::string::npos) << e.what();
  }
  try {
    gp::PrimitiveLibrary::parse(std::regex_replace(text, std::regex("robot->goal@1"), "robot->goal@x"), "ends.yaml");
    ADD_FAILURE() << "an end point role without a step was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("ends.yaml:"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("KIND[+load]->KIND@STEP"), std::string::npos) << e.what();
  }
}

TEST(Roles, NamesStayWhereTheyAreTheRoleAndRolesCostNothingWithoutRoleChanges) {
  // Task 1: several robots per step, each its own shape: the names predict better.
  EXPECT_TRUE(gp::PrimitiveLibrary::fit(test::generated("task1", 20, 1)).roleClasses().empty());
  // Families whose roles move alike (and Task 2, whose first step's two motions move alike):
  // roles, where chosen, predict no worse than names.
  for (const char* family : {"task2", "nearest_goal", "queue", "fetch"}) {
    const gp::PrimitiveLibrary lib = gp::PrimitiveLibrary::fit(test::generated(family, 20, 1));
    const task::TaskDir test = test::generated(family, 10, 99);
    const auto by_role = frechetByKey(lib, test, true), by_name = frechetByKey(lib, test, false);
    double role_sum = 0, name_sum = 0;
    for (const auto& [key, fd] : by_role) role_sum += fd, name_sum += by_name.at(key);
    std::cout << family << ": " << lib.roleClasses().size() << " classes by role, mean FD by role "
              << role_sum / by_role.size() << ", by name " << name_sum / by_name.size() << "\n";
    EXPECT_LE(role_sum, 1.05 * name_sum + 1e-3) << family;
  }
}

TEST(Roles, TheLibraryFileKeepsTheRoles) {
  const gp::PrimitiveLibrary& lib = lineUpLibrary();
  const std::string text = lib.text();
  const gp::PrimitiveLibrary back = gp::PrimitiveLibrary::parse(text, "roles.yaml");
  EXPECT_EQ(back.roleClasses(), lib.roleClasses());
  EXPECT_EQ(back.text(), text);
  const gp::GeneratedPath a = lib.generate("R2:move:R1", {0.1, 0.1}, {0.5, 0.3}, 100, 2),
                          b = back.generate("R2:move:R1", {0.1, 0.1}, {0.5, 0.3}, 100, 2);
  EXPECT_EQ(a.points, b.points);
  EXPECT_EQ(a.source_key, b.source_key);
  // A role in a library of the format before roles, a key that does not say its kinds and
  // step, a kind the library has not: refused, naming the line.
  const auto refused = [&](const std::string& edited, const std::string& expected) {
    ASSERT_NE(edited, text);
    try {
      gp::PrimitiveLibrary::parse(edited, "roles.yaml");
      ADD_FAILURE() << "accepted; expected '" << expected << "'";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(expected), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("roles.yaml:"), std::string::npos) << e.what();
    }
  };
  refused(std::regex_replace(text, std::regex("ddace-primitives/5"), "ddace-primitives/3"), "has no role primitives");
  refused(std::regex_replace(text, std::regex("step: 2"), "step: 3"), "does not match its kinds, action and step");
  refused(std::regex_replace(text, std::regex("entity: robot:hamster"), "entity: robot:uav",
                             std::regex_constants::format_first_only),
          "is no kind of the library's entities");
}
