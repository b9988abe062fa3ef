// A differential-drive robot (Robomation Hamster) as a unicycle, for mock robots and
// the closed-loop simulator.
//
// Owns: the kinematics (integrated at a fixed rate), wheel-speed saturation, command
// latency, a command watchdog (a robot stops when commands stop, like the real one) and
// noise on the *measured* pose. Must not: plan or control (see path_follower.h).
// Units: metres, radians, seconds, m/s; table frame (x, y, yaw counter-clockwise from +x).
#pragma once

#include <cstdint>
#include <deque>
#include <random>

#include <Eigen/Core>

#include "ddace/common/angle.h"

namespace ddace::exec {

/// Planar pose in the table frame.
struct Pose2D {
  double x = 0;    ///< metres
  double y = 0;    ///< metres
  double yaw = 0;  ///< radians, counter-clockwise from +x, in (-pi, pi]
  Eigen::Vector2d position() const { return {x, y}; }
};

/// Ground speeds of the two wheels, m/s, positive = forward.
struct WheelSpeeds {
  double left_mps = 0;
  double right_mps = 0;
  bool isZero() const { return left_mps == 0 && right_mps == 0; }
};

struct DiffDriveParams {
  double rate_hz = 50;                ///< integration rate; step() advances 1/rate_hz seconds
  double wheel_base_m = 0.030;        ///< distance between the wheel contact points (Hamster ~3 cm)
  double max_wheel_speed_mps = 0.20;  ///< each wheel is clamped to +-this
  double latency_s = 0.0;             ///< a command takes effect this long after it is given
  double command_timeout_s = 0.25;    ///< no command for this long -> wheels stop (0 = never)
  double position_noise_m = 0.0;      ///< std-dev of Gaussian noise on measured x and y
  double yaw_noise_rad = 0.0;         ///< std-dev of Gaussian noise on measured yaw
  uint64_t seed = 1;                  ///< noise seed (deterministic runs)

  /// Throws ddace::Error naming the first invalid field.
  void validate() const;
};

/// Calls `visit(name, field)` for every field, by the name config/execution.yaml gives it
/// (mock_robots/robot): the one list the ROS parameters and `ddace eval --config` read.
template <typename Visit>
void visitParams(DiffDriveParams& p, Visit&& visit) {
  visit("rate_hz", p.rate_hz);
  visit("wheel_base_m", p.wheel_base_m);
  visit("max_wheel_speed_mps", p.max_wheel_speed_mps);
  visit("latency_s", p.latency_s);
  visit("command_timeout_s", p.command_timeout_s);
  visit("position_noise_m", p.position_noise_m);
  visit("yaw_noise_rad", p.yaw_noise_rad);
  visit("seed", p.seed);
}

/// The simulated Hamster of the mock robots (config/execution.yaml's mock_robots/robot,
/// checked against this by the params_defaults rostest) and of `ddace eval --execution
/// diffdrive`: 40 ms from a command to the wheels (radio + firmware). Tracking noise is
/// each user's own (eval: --noise).
inline DiffDriveParams simulatedHamster() {
  DiffDriveParams p;
  p.latency_s = 0.04;
  return p;
}

/// Wraps an angle to (-pi, pi] (the one definition is in common/angle.h).
using ddace::wrapAngle;

/// Converts a body twist (v m/s forward, w rad/s counter-clockwise) to wheel speeds.
WheelSpeeds twistToWheels(double v_mps, double w_radps, double wheel_base_m);
/// The unicycle's pose after `dt_s` at forward speed `v_mps` and yaw rate `w_radps`, by
/// exact arc integration (the pose stays on the unicycle's circle at any rate): the one
/// integrator of every simulated robot (DiffDriveModel, the mock Hamster).
Pose2D integrateUnicycle(const Pose2D& pose, double v_mps, double w_radps, double dt_s);

/// One simulated robot. Not thread-safe.
class DiffDriveModel {
 public:
  explicit DiffDriveModel(const DiffDriveParams& params, const Pose2D& initial = {});

  /// A wheel command given at time `now_s` (seconds, the model's clock). It becomes
  /// effective at now_s + latency_s, clamped to the wheel limits.
  void command(const WheelSpeeds& wheels, double now_s);
  /// Advances the true pose by one period (1/rate_hz) ending at `now_s` + period.
  void step();
  /// Blocks the wheels (a stalled robot): commands are accepted but nothing moves.
  void setStalled(bool stalled) { stalled_ = stalled; }
  /// The wheels turn at `gain` (> 0) times the speed applied: a robot slower than its
  /// commands (a weak motor, a low battery). 1 by default.
  void setWheelGain(double gain);

  double time() const { return time_s_; }
  const Pose2D& truePose() const { return pose_; }
  /// Moves the robot to where something else put it (a collision in the table simulator).
  void setTruePose(const Pose2D& pose) { pose_ = {pose.x, pose.y, wrapAngle(pose.yaw)}; }
  /// The true pose plus measurement noise (fresh noise on every call).
  Pose2D measuredPose();
  /// The wheel speeds currently applied (after latency, clamping and watchdog).
  const WheelSpeeds& applied() const { return applied_; }
  const DiffDriveParams& params() const { return params_; }

 private:
  struct Pending {
    double effective_s;
    double given_s;
    WheelSpeeds wheels;
  };
  DiffDriveParams params_;
  Pose2D pose_;
  double time_s_ = 0;
  double last_command_s_ = -1e300;
  WheelSpeeds applied_;
  std::deque<Pending> pending_;
  bool stalled_ = false;
  double wheel_gain_ = 1;
  std::mt19937_64 rng_;
  std::normal_distribution<double> normal_{0.0, 1.0};
};

}  // namespace ddace::exec
