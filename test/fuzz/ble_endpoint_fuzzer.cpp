// libFuzzer target: the BLE endpoint name "ble:<adapter>/<address>" (a port name from
// hamsters.yaml or the command line) is split or refused, never a crash. An accepted name
// has an adapter that is safe as a D-Bus object path element, and it is rebuilt from
// its parts to a name that splits into the same parts.
// fuzz-modules: hamster
#include <cctype>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "ddace/hamster/transport.h"

using namespace ddace::hamster;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string port(reinterpret_cast<const char*>(data), size);
  std::string adapter;
  Address address;
  if (!parseBleEndpoint(port, &adapter, &address)) return 0;
  if (adapter.empty()) std::abort();
  for (char c : adapter)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_') std::abort();
  std::string adapter2;
  Address address2;
  if (!parseBleEndpoint(bleEndpoint(adapter, address), &adapter2, &address2)) std::abort();
  if (adapter2 != adapter || address2 != address) std::abort();
  return 0;
}
