#include "ddace/hamster/ble_transport.h"

#include <poll.h>
#include <strings.h>
#include <systemd/sd-bus.h>

#include <algorithm>
#include <cstring>

#include "ddace/common/clock.h"
#include "ddace/common/error.h"

namespace ddace::hamster {
namespace {

constexpr const char* kBluez = "org.bluez";
constexpr const char* kAdapterIface = "org.bluez.Adapter1";
constexpr const char* kDeviceIface = "org.bluez.Device1";
constexpr const char* kCharIface = "org.bluez.GattCharacteristic1";
// Unread lines kept at most; more means nobody reads, and old sensor lines are stale anyway.
constexpr size_t kMaxUnreadBytes = 64 * 1024;

std::string errorText(const sd_bus_error* e, int r) {
  if (e && sd_bus_error_is_set(e)) return std::string(e->name) + (e->message ? std::string(": ") + e->message : "");
  return std::strerror(r < 0 ? -r : r);
}

bool replyFailed(sd_bus_message* m, std::string* why) {
  if (!sd_bus_message_is_method_error(m, nullptr)) return false;
  *why = errorText(sd_bus_message_get_error(m), sd_bus_message_get_errno(m));
  return true;
}

// The variant at the cursor, consumed only when it holds `signature`.
bool peekVariant(sd_bus_message* m, const char* signature) {
  char type = 0;
  const char* contents = nullptr;
  return sd_bus_message_peek_type(m, &type, &contents) > 0 && type == 'v' && contents &&
         std::strcmp(contents, signature) == 0;
}

bool readBool(sd_bus_message* m, bool* out) {
  int v = 0;
  if (!peekVariant(m, "b") || sd_bus_message_read(m, "v", "b", &v) < 0) return false;
  *out = v != 0;
  return true;
}

bool readString(sd_bus_message* m, std::string* out) {
  const char* s = nullptr;
  if (!peekVariant(m, "s") || sd_bus_message_read(m, "v", "s", &s) < 0) return false;
  *out = s ? s : "";
  return true;
}

// Reads an a{sv} at the cursor. `on(key, m)` consumes the variant and returns true,
// or returns false without touching it (it is skipped). Negative errno on a bad message.
template <typename F>
int readProperties(sd_bus_message* m, F&& on) {
  int r = sd_bus_message_enter_container(m, 'a', "{sv}");
  if (r < 0) return r;
  while ((r = sd_bus_message_enter_container(m, 'e', "sv")) > 0) {
    const char* key = nullptr;
    if ((r = sd_bus_message_read(m, "s", &key)) < 0) return r;
    if (!on(std::string(key), m) && (r = sd_bus_message_skip(m, "v")) < 0) return r;
    if ((r = sd_bus_message_exit_container(m)) < 0) return r;
  }
  if (r < 0) return r;
  return sd_bus_message_exit_container(m);
}

// What BlueZ shows of our adapter, device and characteristics.
struct Listing {
  bool adapter = false;
  bool device = false;
  bool connected = false;
  bool resolved = false;
  std::string sensor_path, effector_path;
};

}  // namespace

enum class BlePhase {
  Closed,
  Listing,      // GetManagedObjects: are adapter and device known?
  Discovering,  // StartDiscovery until the device appears
  Connecting,   // Device1.Connect sent
  Resolving,    // connected, waiting for ServicesResolved
  Finding,      // GetManagedObjects: the two characteristics
  Subscribing,  // StartNotify sent
  Ready,
};

struct BleTransport::Impl {
  std::string endpoint;
  double timeout_s = 20.0;
  bool valid = false;
  std::string adapter;
  Address address;
  std::string adapter_path, device_path;

  sd_bus* bus = nullptr;
  BlePhase phase = BlePhase::Closed;
  double deadline_s = 0.0;
  std::string error;  // set once: the link is gone; read()/write() throw it
  bool connected = false, seen_connected = false, resolved = false, connect_sent = false;
  std::string sensor_path, effector_path;
  std::string rx;  // text lines for read()
  std::string tx;  // a partly written line
  int pending_writes = 0;
  std::string write_error;  // the last acknowledged write failed
  uint64_t malformed = 0;

  void fail(const std::string& why) {
    if (error.empty()) error = endpoint + ": " + why;
  }

  // ---- requests
  void call(const char* path, const char* iface, const char* member, sd_bus_message_handler_t handler,
            const std::string& what) {
    const int r = sd_bus_call_method_async(bus, nullptr, kBluez, path, iface, member, handler, this, "");
    if (r < 0) fail(what + ": cannot send (" + errorText(nullptr, r) + ")");
  }

  void list(BlePhase next) {
    phase = next;
    call("/", "org.freedesktop.DBus.ObjectManager", "GetManagedObjects", &Impl::onList, "GetManagedObjects");
  }

  void discover() {
    phase = BlePhase::Discovering;
    // LE only: the Hamster is a BLE peripheral. A refused filter is harmless.
    sd_bus_message* m = nullptr;
    if (sd_bus_message_new_method_call(bus, &m, kBluez, adapter_path.c_str(), kAdapterIface, "SetDiscoveryFilter") >=
            0 &&
        sd_bus_message_append(m, "a{sv}", 1, "Transport", "s", "le") >= 0) {
      sd_bus_call_async(bus, nullptr, m, &Impl::onIgnored, this, 0);
    }
    sd_bus_message_unref(m);
    call(adapter_path.c_str(), kAdapterIface, "StartDiscovery", &Impl::onStartDiscovery, "StartDiscovery");
  }

  void connect() {
    if (phase == BlePhase::Discovering) {
      // Discovery slows connecting down on many controllers: stop it first.
      sd_bus_call_method_async(bus, nullptr, kBluez, adapter_path.c_str(), kAdapterIface, "StopDiscovery",
                               &Impl::onIgnored, this, "");
    }
    phase = BlePhase::Connecting;
    connect_sent = true;
    call(device_path.c_str(), kDeviceIface, "Connect", &Impl::onConnect, "Connect");
  }

  void subscribe() {
    phase = BlePhase::Subscribing;
    call(sensor_path.c_str(), kCharIface, "StartNotify", &Impl::onStartNotify, "StartNotify");
  }

  void sendPayload(const Payload& payload) {
    sd_bus_message* m = nullptr;
    int r = sd_bus_message_new_method_call(bus, &m, kBluez, effector_path.c_str(), kCharIface, "WriteValue");
    if (r >= 0) r = sd_bus_message_append_array(m, 'y', payload.data(), payload.size());
    // "command" = write without response, as the dongle and the ESP32 client do.
    if (r >= 0) r = sd_bus_message_append(m, "a{sv}", 1, "type", "s", "command");
    if (r >= 0) r = sd_bus_call_async(bus, nullptr, m, &Impl::onWrite, this, 0);
    sd_bus_message_unref(m);
    if (r < 0) throw Error(endpoint + ": WriteValue cannot be sent (" + errorText(nullptr, r) + ")");
    ++pending_writes;
  }

  // ---- parsing
  // a{sa{sv}} of one object at `path` into `out`.
  int parseInterfaces(sd_bus_message* m, const std::string& path, Listing& out) {
    int r = sd_bus_message_enter_container(m, 'a', "{sa{sv}}");
    if (r < 0) return r;
    while ((r = sd_bus_message_enter_container(m, 'e', "sa{sv}")) > 0) {
      const char* iface_c = nullptr;
      if ((r = sd_bus_message_read(m, "s", &iface_c)) < 0) return r;
      const std::string iface = iface_c;
      if (iface == kAdapterIface && path == adapter_path) {
        out.adapter = true;
        r = sd_bus_message_skip(m, "a{sv}");
      } else if (iface == kDeviceIface && path == device_path) {
        out.device = true;
        r = readProperties(m, [&](const std::string& key, sd_bus_message* v) {
          if (key == "Connected") return readBool(v, &out.connected);
          if (key == "ServicesResolved") return readBool(v, &out.resolved);
          return false;
        });
      } else if (iface == kCharIface && path.rfind(device_path + "/", 0) == 0) {
        std::string uuid;
        r = readProperties(
            m, [&](const std::string& key, sd_bus_message* v) { return key == "UUID" && readString(v, &uuid); });
        if (strcasecmp(uuid.c_str(), kHamsterSensorCharUuid) == 0) out.sensor_path = path;
        if (strcasecmp(uuid.c_str(), kHamsterEffectorCharUuid) == 0) out.effector_path = path;
      } else {
        r = sd_bus_message_skip(m, "a{sv}");
      }
      if (r < 0) return r;
      if ((r = sd_bus_message_exit_container(m)) < 0) return r;
    }
    if (r < 0) return r;
    return sd_bus_message_exit_container(m);
  }

  int parseObjects(sd_bus_message* m, Listing& out) {
    int r = sd_bus_message_enter_container(m, 'a', "{oa{sa{sv}}}");
    if (r < 0) return r;
    while ((r = sd_bus_message_enter_container(m, 'e', "oa{sa{sv}}")) > 0) {
      const char* path = nullptr;
      if ((r = sd_bus_message_read(m, "o", &path)) < 0) return r;
      if ((r = parseInterfaces(m, path, out)) < 0) return r;
      if ((r = sd_bus_message_exit_container(m)) < 0) return r;
    }
    if (r < 0) return r;
    return sd_bus_message_exit_container(m);
  }

  void notification(const uint8_t* data, size_t size) {
    if (rx.size() > kMaxUnreadBytes) rx.clear();
    if (size == kPayloadBytes) {
      Payload p;
      std::memcpy(p.data(), data, kPayloadBytes);
      rx += encodeLine(p, address);
      return;
    }
    // Forwarded as the dongle would: RobotLink counts the malformed line and drops it.
    ++malformed;
    rx += hexBytes(data, std::min<size_t>(size, kMaxLineChars)) + "-" + address.wire() + "\r";
  }

  // ---- replies and signals (sd-bus calls these from sd_bus_process in read())
  static Impl* self(void* user) { return static_cast<Impl*>(user); }

  static int onIgnored(sd_bus_message*, void*, sd_bus_error*) { return 0; }

  static int onList(sd_bus_message* m, void* user, sd_bus_error*) {
    Impl* t = self(user);
    std::string why;
    if (replyFailed(m, &why)) {
      t->fail("BlueZ does not answer (" + why + "); is bluetoothd running?");
      return 0;
    }
    Listing l;
    if (t->parseObjects(m, l) < 0) {
      t->fail("malformed GetManagedObjects reply from BlueZ");
      return 0;
    }
    if (!l.adapter) {
      t->fail("BlueZ has no adapter " + t->adapter + " (see bluetoothctl list)");
      return 0;
    }
    if (t->phase == BlePhase::Listing) {
      if (!l.device) {
        t->discover();
        return 0;
      }
      t->connected = l.connected;
      t->resolved = l.resolved;
      t->connect();
    } else if (t->phase == BlePhase::Finding) {
      if (!l.device) {
        t->fail("the robot vanished from BlueZ while connecting");
      } else if (!l.sensor_path.empty() && !l.effector_path.empty()) {
        t->sensor_path = l.sensor_path;
        t->effector_path = l.effector_path;
        t->subscribe();
      } else if (!l.resolved) {
        t->resolved = false;
        t->phase = BlePhase::Resolving;  // services still being discovered
      } else {
        t->fail(std::string("the device has no Hamster ") +
                (l.sensor_path.empty() ? "sensor characteristic " + std::string(kHamsterSensorCharUuid)
                                       : "effector characteristic " + std::string(kHamsterEffectorCharUuid)) +
                "; is it an original Hamster? (a Hamster-S cannot be driven over BLE)");
      }
    }
    return 0;
  }

  static int onStartDiscovery(sd_bus_message* m, void* user, sd_bus_error*) {
    Impl* t = self(user);
    std::string why;
    // InProgress: another client is discovering already, which serves us as well.
    if (replyFailed(m, &why) && why.rfind("org.bluez.Error.InProgress", 0) != 0) {
      t->fail("StartDiscovery on " + t->adapter + " failed (" + why +
              "); is the adapter powered (bluetoothctl power on)?");
    }
    return 0;
  }

  static int onConnect(sd_bus_message* m, void* user, sd_bus_error*) {
    Impl* t = self(user);
    std::string why;
    if (replyFailed(m, &why) && why.rfind("org.bluez.Error.AlreadyConnected", 0) != 0) {
      t->fail("Connect failed (" + why + "); is the robot on, in range and not connected to another host?");
      return 0;
    }
    if (t->phase != BlePhase::Connecting) return 0;
    t->connected = t->seen_connected = true;
    if (t->resolved) {
      t->list(BlePhase::Finding);
    } else {
      t->phase = BlePhase::Resolving;
    }
    return 0;
  }

  static int onStartNotify(sd_bus_message* m, void* user, sd_bus_error*) {
    Impl* t = self(user);
    std::string why;
    if (replyFailed(m, &why)) {
      t->fail("StartNotify on the sensor characteristic failed (" + why + ")");
    } else if (t->phase == BlePhase::Subscribing) {
      t->phase = BlePhase::Ready;
    }
    return 0;
  }

  static int onWrite(sd_bus_message* m, void* user, sd_bus_error*) {
    Impl* t = self(user);
    if (t->pending_writes > 0) --t->pending_writes;
    std::string why;
    if (replyFailed(m, &why)) {
      t->write_error = t->endpoint + ": WriteValue failed (" + why + ")";
    } else {
      t->write_error.clear();
    }
    return 0;
  }

  static int onPropertiesChanged(sd_bus_message* m, void* user, sd_bus_error*) {
    Impl* t = self(user);
    const char* path_c = sd_bus_message_get_path(m);
    const char* iface_c = nullptr;
    if (!path_c || sd_bus_message_read(m, "s", &iface_c) < 0) return 0;
    const std::string path = path_c, iface = iface_c;
    if (path == t->device_path && iface == kDeviceIface) {
      readProperties(m, [&](const std::string& key, sd_bus_message* v) {
        bool b = false;
        if (key == "Connected" && readBool(v, &b)) {
          t->connected = b;
          if (b) t->seen_connected = true;
          if (!b && t->seen_connected) t->fail("the robot disconnected (BlueZ Device1.Connected=false)");
          return true;
        }
        if (key == "ServicesResolved" && readBool(v, &b)) {
          t->resolved = b;
          // Services going away while connected is reported by the removal of our
          // characteristics (InterfacesRemoved), a disconnect by Connected=false.
          if (b && t->phase == BlePhase::Resolving) t->list(BlePhase::Finding);
          return true;
        }
        return false;
      });
    } else if (path == t->sensor_path && iface == kCharIface) {
      readProperties(m, [&](const std::string& key, sd_bus_message* v) {
        if (key == "Value" && peekVariant(v, "ay")) {
          const void* data = nullptr;
          size_t size = 0;
          if (sd_bus_message_enter_container(v, 'v', "ay") < 0) return false;
          if (sd_bus_message_read_array(v, 'y', &data, &size) >= 0 &&
              (t->phase == BlePhase::Subscribing || t->phase == BlePhase::Ready)) {
            t->notification(static_cast<const uint8_t*>(data), size);
          }
          sd_bus_message_exit_container(v);
          return true;
        }
        bool b = true;
        if (key == "Notifying" && readBool(v, &b)) {
          if (!b && t->phase == BlePhase::Ready) t->fail("BlueZ stopped the sensor notifications");
          return true;
        }
        return false;
      });
    }
    return 0;
  }

  static int onInterfacesAdded(sd_bus_message* m, void* user, sd_bus_error*) {
    Impl* t = self(user);
    const char* path = nullptr;
    if (sd_bus_message_read(m, "o", &path) < 0 || t->device_path != path) return 0;
    Listing l;
    if (t->parseInterfaces(m, path, l) < 0 || !l.device) return 0;
    t->connected = l.connected;
    t->resolved = l.resolved;
    if (t->phase == BlePhase::Discovering) t->connect();
    return 0;
  }

  static int onInterfacesRemoved(sd_bus_message* m, void* user, sd_bus_error*) {
    Impl* t = self(user);
    const char* path_c = nullptr;
    if (sd_bus_message_read(m, "o", &path_c) < 0 || sd_bus_message_enter_container(m, 'a', "s") < 0) return 0;
    const std::string path = path_c;
    const char* iface = nullptr;
    while (sd_bus_message_read(m, "s", &iface) > 0) {
      if (path == t->device_path && std::strcmp(iface, kDeviceIface) == 0) {
        t->fail("the robot's device object vanished from BlueZ (removed, or out of range)");
      } else if (path == t->adapter_path && std::strcmp(iface, kAdapterIface) == 0) {
        t->fail("adapter " + t->adapter + " was removed");
      } else if (t->phase == BlePhase::Ready && (path == t->sensor_path || path == t->effector_path)) {
        t->fail("the robot's GATT characteristic " + path + " vanished from BlueZ");
      }
    }
    return 0;
  }

  static int onNameOwnerChanged(sd_bus_message* m, void* user, sd_bus_error*) {
    const char *name = nullptr, *old_owner = nullptr, *new_owner = nullptr;
    if (sd_bus_message_read(m, "sss", &name, &old_owner, &new_owner) < 0) return 0;
    if (std::strcmp(name, kBluez) == 0 && (!new_owner || !*new_owner)) {
      self(user)->fail("BlueZ (bluetoothd) left the system bus");
    }
    return 0;
  }

  // ---- lifetime
  void open() {
    close();
    if (!valid) {
      throw Error("'" + endpoint + "' is not a BLE endpoint ble:<adapter>/<AA:BB:CC:DD:EE:FF>");
    }
    error.clear();
    write_error.clear();
    rx.clear();
    tx.clear();
    connected = seen_connected = resolved = connect_sent = false;
    sensor_path.clear();
    effector_path.clear();
    pending_writes = 0;
    malformed = 0;
    int r = sd_bus_open_system(&bus);
    if (r < 0) {
      bus = nullptr;
      throw Error(endpoint + ": cannot connect to the system D-Bus (" + errorText(nullptr, r) + "); is dbus running?");
    }
    sd_bus_set_exit_on_disconnect(bus, 0);  // a lost bus is a lost link, not the end of the process
    // Signals first: the daemon handles our messages in order, so nothing that
    // happens after the listing below can be missed.
    const std::string props =
        "type='signal',interface='org.freedesktop.DBus.Properties',member='PropertiesChanged',"
        "path_namespace='" +
        device_path + "'";
    r = sd_bus_add_match_async(bus, nullptr, props.c_str(), &Impl::onPropertiesChanged, nullptr, this);
    if (r >= 0) {
      r = sd_bus_match_signal_async(bus, nullptr, nullptr, nullptr, "org.freedesktop.DBus.ObjectManager",
                                    "InterfacesAdded", &Impl::onInterfacesAdded, nullptr, this);
    }
    if (r >= 0) {
      r = sd_bus_match_signal_async(bus, nullptr, nullptr, nullptr, "org.freedesktop.DBus.ObjectManager",
                                    "InterfacesRemoved", &Impl::onInterfacesRemoved, nullptr, this);
    }
    if (r >= 0) {
      r = sd_bus_add_match_async(bus, nullptr,
                                 "type='signal',sender='org.freedesktop.DBus',member='NameOwnerChanged',"
                                 "arg0='org.bluez'",
                                 &Impl::onNameOwnerChanged, nullptr, this);
    }
    if (r < 0) {
      const std::string why = errorText(nullptr, r);
      close();
      throw Error(endpoint + ": cannot subscribe to BlueZ signals (" + why + ")");
    }
    deadline_s = monotonicS() + timeout_s;
    list(BlePhase::Listing);
    if (!error.empty()) {
      const std::string why = error;
      close();
      throw Error(why);
    }
  }

  void close() {
    if (!bus) return;
    if (connect_sent && (connected || !seen_connected)) {
      // Like pulling the dongle: the next open() starts from a fresh connection.
      sd_bus_message* m = nullptr;
      if (sd_bus_message_new_method_call(bus, &m, kBluez, device_path.c_str(), kDeviceIface, "Disconnect") >= 0 &&
          sd_bus_message_set_expect_reply(m, 0) >= 0) {
        sd_bus_send(bus, m, nullptr);
      }
      sd_bus_message_unref(m);
    }
    // Hand the queued messages (the last zero-wheel write, Disconnect) to the socket,
    // waiting briefly at most. Closed first: replies processed meanwhile start nothing new.
    phase = BlePhase::Closed;
    const double end = monotonicS() + 0.1;
    uint64_t queued = 0;
    while (sd_bus_get_n_queued_write(bus, &queued) >= 0 && queued > 0 && monotonicS() < end) {
      if (sd_bus_process(bus, nullptr) > 0) continue;
      const int fd = sd_bus_get_fd(bus), events = sd_bus_get_events(bus);
      if (fd < 0 || events < 0) break;
      pollfd p{fd, static_cast<short>(events), 0};
      ::poll(&p, 1, 10);
    }
    bus = sd_bus_close_unref(bus);
    phase = BlePhase::Closed;
  }

  size_t read(char* buf, size_t size) {
    if (!bus) throw Error(endpoint + ": not open");
    for (int i = 0; i < 256; ++i) {  // bounded: a flood of signals must not stall the caller
      const int r = sd_bus_process(bus, nullptr);
      if (r < 0) {
        fail("D-Bus connection lost (" + errorText(nullptr, r) + ")");
        break;
      }
      if (r == 0) break;
    }
    if (error.empty() && phase != BlePhase::Ready && monotonicS() > deadline_s) timeoutError();
    if (!error.empty()) throw Error(error);
    const size_t n = std::min(size, rx.size());
    rx.copy(buf, n);
    rx.erase(0, n);
    return n;
  }

  void timeoutError() {
    const std::string within = " within " + std::to_string(timeout_s) + " s";
    switch (phase) {
      case BlePhase::Discovering:
        fail("adapter " + adapter + " did not find the robot" + within +
             " (switched on? in range? connected to another host or dongle?)");
        break;
      case BlePhase::Connecting:
        fail("no connection" + within);
        break;
      case BlePhase::Resolving:
      case BlePhase::Finding:
        fail("the robot's GATT services were not resolved" + within);
        break;
      case BlePhase::Subscribing:
        fail("sensor notifications did not start" + within);
        break;
      default:
        fail("BlueZ did not answer" + within + "; is bluetoothd running?");
        break;
    }
  }

  void write(const char* data, size_t size) {
    if (!bus) throw Error(endpoint + ": not open");
    if (!error.empty()) throw Error(error);
    tx.append(data, size);
    size_t start = 0;
    for (size_t i = 0; i < tx.size(); ++i) {
      if (tx[i] != '\r' && tx[i] != '\n') continue;
      const std::string line = tx.substr(start, i - start);
      start = i + 1;
      if (line.empty()) continue;
      try {
        sendLine(line);
      } catch (const Error&) {
        tx.erase(0, start);
        throw;
      }
    }
    tx.erase(0, start);
    if (tx.size() > kMaxLineChars) {
      tx.clear();
      throw Error(endpoint + ": line longer than " + std::to_string(kMaxLineChars) + " characters written");
    }
    if (!write_error.empty()) throw Error(write_error);
  }

  void sendLine(const std::string& line) {
    if (line == "FF") {
      // Answered locally once the connection stands (unanswered before, as a
      // dongle whose robot is not linked yet).
      if (phase == BlePhase::Ready) {
        IdentifyReply reply;
        reply.name = "Hamster";
        reply.model = Model::Hamster;
        reply.model_code = static_cast<uint8_t>(Model::Hamster);
        reply.info = "BLE";
        reply.address = address;
        rx += encodeIdentifyReply(reply) + "\r";
      }
      return;
    }
    const ParsedLine parsed = parseLine(line);
    if (parsed.kind != LineKind::Data) {
      throw Error(endpoint + ": cannot send '" + line.substr(0, 60) + "' over BLE (" +
                  (parsed.error.empty() ? std::string("not a motoring line") : parsed.error) + ")");
    }
    if (parsed.address != address) {
      throw Error(endpoint + ": motoring line for " + parsed.address.display() + " refused");
    }
    if (phase != BlePhase::Ready) throw Error(endpoint + ": not connected yet");
    // A stop always goes out: it is what RobotLink sends when it gives the link up, which is
    // exactly when writes are backed up.
    const auto effector = decodeEffector(Model::Hamster, parsed.payload);
    const bool stop = effector && effector->left_wheel == 0 && effector->right_wheel == 0;
    if (pending_writes >= kMaxPendingWrites && !stop) {
      throw Error(endpoint + ": " + std::to_string(pending_writes) +
                  " GATT writes not acknowledged by BlueZ; command dropped");
    }
    sendPayload(parsed.payload);
  }
};

BleTransport::BleTransport(std::string endpoint, double connect_timeout_s) : impl_(std::make_unique<Impl>()) {
  impl_->endpoint = std::move(endpoint);
  impl_->timeout_s = connect_timeout_s;
  impl_->valid = parseBleEndpoint(impl_->endpoint, &impl_->adapter, &impl_->address);
  if (impl_->valid) {
    impl_->adapter_path = "/org/bluez/" + impl_->adapter;
    std::string dev = impl_->address.display();
    for (char& c : dev) c = c == ':' ? '_' : c;
    impl_->device_path = impl_->adapter_path + "/dev_" + dev;
  }
}

BleTransport::~BleTransport() {
  impl_->close();
}

void BleTransport::open() {
  impl_->open();
}
void BleTransport::close() {
  impl_->close();
}
bool BleTransport::isOpen() const {
  return impl_->bus != nullptr;
}
size_t BleTransport::read(char* buf, size_t size) {
  return impl_->read(buf, size);
}
void BleTransport::write(const char* data, size_t size) {
  impl_->write(data, size);
}

void BleTransport::flush() {
  impl_->rx.clear();
  impl_->tx.clear();
}

int BleTransport::fd() const {
  if (!impl_->bus) return -1;
  const int fd = sd_bus_get_fd(impl_->bus);
  return fd < 0 ? -1 : fd;
}

bool BleTransport::connecting() const {
  return impl_->bus && impl_->error.empty() && impl_->phase != BlePhase::Ready;
}

std::string BleTransport::name() const {
  return impl_->endpoint;
}
uint64_t BleTransport::malformedNotifications() const {
  return impl_->malformed;
}
std::string BleTransport::devicePath() const {
  return impl_->device_path;
}

TransportFactory bleTransportFactory(double connect_timeout_s) {
  return [connect_timeout_s](const std::string& port) -> std::unique_ptr<Transport> {
    return std::make_unique<BleTransport>(port, connect_timeout_s);
  };
}

}  // namespace ddace::hamster
