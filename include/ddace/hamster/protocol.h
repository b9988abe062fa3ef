// The Hamster radio protocol as seen on the USB dongle's serial port.
//
// Owns: encoding of the 20-byte effector ("motoring") payload and decoding of the
// 20-byte sensor payload of the original Hamster (model code 0x04) and the Hamster-S
// (0x0E); the text framing (40 upper-case hex digits, '-', 12-hex-digit robot
// address, CR); the `FF` identification reply; line reassembly from a byte stream.
// Facts and their public sources: docs/hamster-protocol.md (our own implementation).
//
// Must not: touch a file descriptor, a clock or ROS. Parsing never throws and never
// crashes on any input: a malformed line is reported as LineKind::Malformed with a
// reason, so callers can count and drop it.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace ddace::hamster {

/// Model code as reported in the `FF` reply (field 2).
enum class Model : uint8_t {
  Unknown = 0x00,
  Hamster = 0x04,   ///< the original Hamster
  HamsterS = 0x0E,  ///< Hamster-S
};

/// "hamster", "hamster_s" or "unknown".
std::string modelName(Model model);

/// Payload size in bytes (both directions, both models).
constexpr size_t kPayloadBytes = 20;
/// Characters of a data line without its CR: 40 hex + '-' + 12 hex.
constexpr size_t kDataLineChars = 53;
/// Wheel command range in robot units (percent of full speed, open loop).
constexpr int kMaxWheelUnits = 100;
/// Longest line the assembler keeps; anything longer is discarded as overlong.
constexpr size_t kMaxLineChars = 128;

using Payload = std::array<uint8_t, kPayloadBytes>;

/// A robot's 6-byte Bluetooth address in *wire* byte order (the order of the 12 hex
/// digits on the serial line). Users usually see the reversed, colon-separated form.
struct Address {
  std::array<uint8_t, 6> bytes{};

  /// 12 upper-case hex digits, wire order, e.g. "67E1A48B4BD9".
  std::string wire() const;
  /// Colon form in the usual Bluetooth order (bytes reversed), e.g. "D9:4B:8B:A4:E1:67".
  std::string display() const;
  bool operator==(const Address& o) const { return bytes == o.bytes; }
  bool operator!=(const Address& o) const { return bytes != o.bytes; }

  /// Accepts 12 hex digits (wire order) or the colon form AA:BB:CC:DD:EE:FF (display
  /// order, reversed into wire order). Case-insensitive. nullopt when malformed.
  static std::optional<Address> parse(std::string_view text);
};

/// What the host wants the robot to do. Common to both models; the encoder maps it
/// onto each model's layout.
struct Effector {
  int8_t left_wheel = 0;   ///< robot units, -100..100 (clamped by the encoder)
  int8_t right_wheel = 0;  ///< robot units, -100..100
  /// LED colours, 0..255 per channel. The original Hamster has 8 colours only: a
  /// channel counts as on when >= 128.
  std::array<uint8_t, 3> left_led_rgb{};
  std::array<uint8_t, 3> right_led_rgb{};
  double buzzer_hz = 0.0;  ///< 0 = silent; clamped to 0..6500 Hz
  uint8_t note = 0;        ///< 0 = off, 1..88 = piano key (49 = A4); wins over the buzzer
};

/// Encodes the 20-byte effector payload for `model` (Hamster or HamsterS; Unknown is
/// encoded as Hamster). Configuration bytes get the libraries' defaults (proximity
/// IR current 2, line tracer off, I/O ports analog input).
Payload encodeEffector(Model model, const Effector& effector);

/// The full line: 40 hex digits, '-', address.wire(), '\r' (54 characters).
std::string encodeLine(const Payload& payload, const Address& address);

/// Upper-case hex, two digits per byte, most significant nibble first (the line
/// encoding of any byte string, e.g. a BLE notification of the wrong length).
std::string hexBytes(const uint8_t* data, size_t size);

/// The identification request the host sends: "FF\r".
constexpr std::string_view kIdentifyRequest = "FF\r";

/// Sensor values decoded from one sensor payload. Fields a model or a packet does
/// not carry are left unset (has_* = false).
struct Sensors {
  Model model = Model::Unknown;
  uint8_t proximity_left = 0;  ///< front IR proximity, raw 0..255 (scale undocumented)
  uint8_t proximity_right = 0;
  uint8_t floor_left = 0;  ///< downward IR floor sensor, raw 0..255 (scale undocumented)
  uint8_t floor_right = 0;
  /// Accelerometer, raw signed counts; x forward, y left, z up (about 16384 per g at
  /// the default range, unverified).
  int16_t accel_x = 0, accel_y = 0, accel_z = 0;
  int8_t rssi_dbm = 0;               ///< radio signal strength, dBm (-128..0)
  uint8_t input_a = 0, input_b = 0;  ///< external I/O ports, raw
  bool has_light = false;
  uint16_t light = 0;  ///< raw ambient light (unit undocumented)
  bool has_temperature = false;
  double temperature_c = 0.0;
  bool has_battery = false;
  double battery_v = 0.0;
  // Hamster-S only.
  bool has_pulse_count = false;
  uint16_t pulse_count = 0;  ///< wheel pulses (about 138 per cm)
};

/// Decodes a sensor payload of `model`. Returns nullopt and sets `why` when the
/// packet-type bits do not mark a sensor packet of that model (for the Hamster-S a
/// serial pass-through packet, type 2, is also refused: "serial pass-through packet").
std::optional<Sensors> decodeSensors(Model model, const Payload& payload, std::string* why = nullptr);

/// Inverse of decodeSensors, used by the mock robot and tests. Only the fields the
/// model carries are written; `light_packet` chooses light (true) or
/// temperature + battery (false) for the shared bytes.
Payload encodeSensors(Model model, const Sensors& sensors, bool light_packet);

/// Decodes an effector payload (used by the mock robot). nullopt with `why` when the
/// command byte is not a motoring command of that model.
std::optional<Effector> decodeEffector(Model model, const Payload& payload, std::string* why = nullptr);

/// The `FF` identification reply: "FF,<name>,<model hex>,<info>,<address>".
struct IdentifyReply {
  std::string name;  ///< e.g. "Hamster"
  Model model = Model::Unknown;
  uint8_t model_code = 0;  ///< the raw model code (may be a robot we do not drive)
  std::string info;        ///< field 3, undocumented (firmware version?)
  Address address;
};

/// "FF,<name>,<model hex>,<info>,<address wire>" without CR.
std::string encodeIdentifyReply(const IdentifyReply& reply);

/// What a complete line (without its CR) is.
enum class LineKind {
  Data,       ///< 40 hex + '-' + 12 hex: payload and address are set
  Identify,   ///< an FF reply: identify is set
  NoRobot,    ///< one character: the dongle has no robot linked
  Malformed,  ///< anything else: error says why
};

struct ParsedLine {
  LineKind kind = LineKind::Malformed;
  Payload payload{};
  Address address;
  IdentifyReply identify;
  std::string error;  ///< for Malformed: what is wrong and at which character (1-based)
};

/// Classifies and parses one line (CR already removed). Never throws.
ParsedLine parseLine(std::string_view line);

/// Splits a byte stream into CR-terminated lines. LF is treated as a line end too,
/// so "\r\n" yields one line. Lines longer than kMaxLineChars are dropped whole
/// (counted in overlong()).
class LineAssembler {
 public:
  /// Appends bytes; calls `on_line(std::string_view)` for every completed non-empty
  /// line, in order. The view is valid during the call only.
  template <typename F>
  void push(const char* data, size_t size, F&& on_line) {
    for (size_t i = 0; i < size; ++i) {
      const char c = data[i];
      if (c == '\r' || c == '\n') {
        if (discarding_) {
          discarding_ = false;
        } else if (length_ > 0) {
          on_line(std::string_view(buffer_.data(), length_));
        }
        length_ = 0;
      } else if (!discarding_) {
        if (length_ == buffer_.size()) {
          discarding_ = true;
          length_ = 0;
          ++overlong_;
        } else {
          buffer_[length_++] = c;
        }
      }
    }
  }
  /// Forgets a partial line (after a reconnect).
  void reset() {
    length_ = 0;
    discarding_ = false;
  }
  /// Bytes of the partial line waiting for its CR.
  size_t pending() const { return length_; }
  uint64_t overlong() const { return overlong_; }

 private:
  std::array<char, kMaxLineChars> buffer_{};
  size_t length_ = 0;
  bool discarding_ = false;
  uint64_t overlong_ = 0;
};

}  // namespace ddace::hamster
