// libFuzzer target: the task.yaml reader must reject or accept any bytes, never crash.
// What is accepted must survive the writer and the reader again with the same content.
// fuzz-modules: task
#include <cstdint>
#include <cstdlib>
#include <string>

#include "ddace/task/task_spec.h"

using namespace ddace::task;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  TaskSpec spec;
  try {
    spec = parseTaskYaml(std::string(reinterpret_cast<const char*>(data), size), "fuzz.yaml");
  } catch (const ddace::Error&) {
    return 0;
  }
  TaskSpec again;
  try {
    again = parseTaskYaml(taskYamlText(spec), "again.yaml");
  } catch (const ddace::Error&) {
    std::abort();  // ddace wrote a task.yaml it refuses
  }
  if (again.name != spec.name || again.entityNames() != spec.entityNames() || again.actions != spec.actions ||
      again.arrival_radius != spec.arrival_radius || again.goal_conditions.size() != spec.goal_conditions.size() ||
      again.action_rules.size() != spec.action_rules.size())
    std::abort();
  for (size_t i = 0; i < spec.action_rules.size(); ++i) {
    const ActionRule &a = again.action_rules[i], &b = spec.action_rules[i];
    if (a.mover_kind != b.mover_kind || a.mover_type != b.mover_type || a.target_kind != b.target_kind ||
        a.target_type != b.target_type || a.load != b.load || a.action != b.action)
      std::abort();
  }
  for (size_t i = 0; i < spec.entities.size(); ++i)
    if (again.entities[i].kind != spec.entities[i].kind || again.entities[i].type != spec.entities[i].type ||
        again.entities[i].radius_m != spec.entities[i].radius_m ||
        again.entities[i].obstacle != spec.entities[i].obstacle)
      std::abort();
  return 0;
}
