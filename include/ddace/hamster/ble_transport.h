// Direct Bluetooth LE to an original Hamster through BlueZ, without a dongle.
//
// Owns: BleTransport, a Transport that presents the dongle's text protocol over
// GATT, so RobotLink and the bridge drive a BLE robot exactly as a dongle:
//   - every 20-byte notification of the sensor characteristic 0000900a-… (service
//     00009001-9c80-11e3-a5e2-0800200c9a66) becomes one 54-character sensor line
//     with the robot's address. A notification of another length becomes a line of
//     that length, which RobotLink counts and drops as malformed;
//   - every motoring line written is parsed and its 20-byte payload written without
//     response to the effector characteristic 0000a006-… (service 0000a000-…);
//   - "FF\r" is answered locally with "FF,Hamster,04,BLE,<address, wire order>".
// BlueZ is reached over the system D-Bus with sd-bus (libsystemd); the bus address
// honours DBUS_SYSTEM_BUS_ADDRESS. Used: ObjectManager.GetManagedObjects (adapter,
// device, GATT characteristics by UUID under the device), Adapter1.StartDiscovery
// when BlueZ does not know the device yet, Device1.Connect, StartNotify,
// PropertiesChanged "Value" signals, WriteValue with {"type": "command"}.
// Every call returns at once: open() connects to the bus and sends the first
// request; the connection proceeds inside read() while connecting() is true.
// Lost link: Device1.Connected=false, the device or adapter vanishing, BlueZ leaving
// the bus, a failed request, a broken bus, or no working connection within the
// connect timeout make read() and write() throw ddace::Error (RobotLink then closes
// and reconnects, as for an unplugged dongle).
// Must not: decide anything about the robot (RobotLink does), pair or trust devices
// (the Hamster needs no pairing), or drive a Hamster-S (its GATT layout is unknown).
// Built only with the CMake option DDACE_WITH_BLE (libsystemd-dev). Tested against a
// mock BlueZ on a private bus (test/unit/hamster/test_ble.cpp), never against a
// real adapter or robot.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "ddace/hamster/transport.h"

namespace ddace::hamster {

/// The two GATT characteristics of the original Hamster (lower case, as BlueZ reports them).
constexpr const char* kHamsterSensorCharUuid = "0000900a-9c80-11e3-a5e2-0800200c9a66";
constexpr const char* kHamsterEffectorCharUuid = "0000a006-9c80-11e3-a5e2-0800200c9a66";

class BleTransport : public Transport {
 public:
  /// `endpoint`: a bleEndpoint() name, "ble:<adapter>/<address>" (checked by open()).
  /// `connect_timeout_s`: from open() until notifications are on, seconds.
  explicit BleTransport(std::string endpoint, double connect_timeout_s = 20.0);
  ~BleTransport() override;  ///< close()

  /// Connects to the system bus and starts the connection (non-blocking). Throws
  /// ddace::Error when the endpoint name is malformed or there is no system bus.
  void open() override;
  /// Asks BlueZ to disconnect the robot (best effort, after the queued writes) and
  /// leaves the bus. Waits at most 0.1 s for the bus socket to take the messages.
  void close() override;
  bool isOpen() const override;
  /// Runs the bus (connection steps, notifications) and returns the text lines made
  /// so far. Returns 0 while connecting. Throws on a lost link (see above).
  size_t read(char* buf, size_t size) override;
  /// Takes text lines (whole or in pieces): "FF\r" is answered by the next read();
  /// a motoring line for our address sends its payload. Throws for any other line,
  /// before the connection stands, on a lost link, when kMaxPendingWrites writes are
  /// still unacknowledged by BlueZ (a stale command is never queued; a stop, zero on
  /// both wheels, always goes out), and when the
  /// last acknowledged write failed (the current line is sent nevertheless).
  void write(const char* data, size_t size) override;
  /// Drops unread lines and a partly written line (sent writes cannot be recalled).
  void flush() override;
  /// The bus socket, for poll(2); -1 when closed.
  int fd() const override;
  bool connecting() const override;
  /// The endpoint name given to the constructor.
  std::string name() const override;

  /// Notifications whose length was not 20 bytes, since open().
  uint64_t malformedNotifications() const;
  /// BlueZ's object path of the robot, e.g. /org/bluez/hci0/dev_D9_4B_8B_A4_E1_67
  /// (empty when the endpoint name is malformed).
  std::string devicePath() const;

  /// GATT writes in flight (sent to BlueZ, not yet acknowledged) beyond which
  /// write() refuses new lines, except a stop (zero on both wheels).
  static constexpr int kMaxPendingWrites = 4;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// The factory RobotLink uses for BLE robots: `port` is a bleEndpoint() name.
TransportFactory bleTransportFactory(double connect_timeout_s);

}  // namespace ddace::hamster
