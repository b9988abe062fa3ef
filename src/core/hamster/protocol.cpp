#include "ddace/hamster/protocol.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace ddace::hamster {
namespace {

constexpr char kHexDigits[] = "0123456789ABCDEF";

int hexValue(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  return -1;
}

// Parses 2*n hex digits at text[0..]; returns the index of the first bad character
// or -1 when all are hex.
int parseHexBytes(std::string_view text, uint8_t* out, size_t n) {
  for (size_t i = 0; i < n; ++i) {
    const int hi = hexValue(text[2 * i]);
    if (hi < 0) return static_cast<int>(2 * i);
    const int lo = hexValue(text[2 * i + 1]);
    if (lo < 0) return static_cast<int>(2 * i + 1);
    out[i] = static_cast<uint8_t>(hi << 4 | lo);
  }
  return -1;
}

void appendHex(std::string& out, uint8_t byte) {
  out += kHexDigits[byte >> 4];
  out += kHexDigits[byte & 0x0F];
}

uint8_t clampByte(long v, long lo, long hi) {
  return static_cast<uint8_t>(std::clamp(v, lo, hi));
}

int8_t clampWheel(int8_t v) {
  return static_cast<int8_t>(std::clamp<int>(v, -kMaxWheelUnits, kMaxWheelUnits));
}

// The original Hamster has 8 LED colours: bit 0 blue, bit 1 green, bit 2 red.
uint8_t colourIndex(const std::array<uint8_t, 3>& rgb) {
  return static_cast<uint8_t>((rgb[0] >= 128 ? 4 : 0) | (rgb[1] >= 128 ? 2 : 0) | (rgb[2] >= 128 ? 1 : 0));
}

std::array<uint8_t, 3> colourRgb(uint8_t index) {
  return {static_cast<uint8_t>(index & 4 ? 255 : 0), static_cast<uint8_t>(index & 2 ? 255 : 0),
          static_cast<uint8_t>(index & 1 ? 255 : 0)};
}

int16_t readS16(const Payload& p, size_t i) {
  return static_cast<int16_t>(p[i] << 8 | p[i + 1]);
}
uint16_t readU16(const Payload& p, size_t i) {
  return static_cast<uint16_t>(p[i] << 8 | p[i + 1]);
}
void writeU16(Payload& p, size_t i, uint16_t v) {
  p[i] = static_cast<uint8_t>(v >> 8);
  p[i + 1] = static_cast<uint8_t>(v & 0xFF);
}

void setWhy(std::string* why, const std::string& text) {
  if (why) *why = text;
}

}  // namespace

std::string modelName(Model model) {
  switch (model) {
    case Model::Hamster:
      return "hamster";
    case Model::HamsterS:
      return "hamster_s";
    default:
      return "unknown";
  }
}

std::string Address::wire() const {
  std::string out;
  for (uint8_t b : bytes) appendHex(out, b);
  return out;
}

std::string Address::display() const {
  std::string out;
  for (size_t i = 0; i < bytes.size(); ++i) {
    if (i) out += ':';
    appendHex(out, bytes[bytes.size() - 1 - i]);
  }
  return out;
}

std::optional<Address> Address::parse(std::string_view text) {
  Address a;
  if (text.size() == 12) {
    if (parseHexBytes(text, a.bytes.data(), 6) >= 0) return std::nullopt;
    return a;
  }
  if (text.size() == 17) {
    for (size_t i = 0; i < 6; ++i) {
      if (i < 5 && text[3 * i + 2] != ':') return std::nullopt;
      uint8_t b = 0;
      if (parseHexBytes(text.substr(3 * i, 2), &b, 1) >= 0) return std::nullopt;
      a.bytes[5 - i] = b;  // the colon form is the reversed (display) order
    }
    return a;
  }
  return std::nullopt;
}

Payload encodeEffector(Model model, const Effector& e) {
  Payload p{};
  const int8_t left = clampWheel(e.left_wheel), right = clampWheel(e.right_wheel);
  const double hz = std::isfinite(e.buzzer_hz) ? std::clamp(e.buzzer_hz, 0.0, 6500.0) : 0.0;
  const uint8_t note = e.note <= 88 ? e.note : 0;
  if (model == Model::HamsterS) {
    p[0] = 0x10;  // sensor-data type, motor mode "auto"
    p[1] = static_cast<uint8_t>(left);
    p[2] = static_cast<uint8_t>(right);
    for (size_t i = 0; i < 3; ++i) {
      p[3 + i] = e.left_led_rgb[i];
      p[6 + i] = e.right_led_rgb[i];
    }
    // bytes 9..11: no counted wheel move; 12: line tracer off
    p[13] = 0x54;  // line-tracer speed 5, gain 4
    p[14] = 0x40;  // IR current 2 (bits 7..5), bandwidth 0, gravity range 0
    // bytes 15..17: I/O ports analog input, outputs 0
    if (note != 0) {
      p[18] = 0x01;
      p[19] = note;
    } else {
      // A buzzer value is round(Hz * 10) + 512; 0x0200 = silent.
      writeU16(p, 18, static_cast<uint16_t>(std::lround(hz * 10.0) + 512));
    }
    return p;
  }
  p[2] = 0x10;  // normal motoring command
  p[3] = static_cast<uint8_t>(left);
  p[4] = static_cast<uint8_t>(right);
  p[5] = colourIndex(e.left_led_rgb);
  p[6] = colourIndex(e.right_led_rgb);
  if (note != 0) {
    p[10] = note;
  } else {
    const auto centi_hz = static_cast<uint32_t>(std::lround(hz * 100.0));
    p[7] = static_cast<uint8_t>(centi_hz >> 16);
    p[8] = static_cast<uint8_t>(centi_hz >> 8);
    p[9] = static_cast<uint8_t>(centi_hz);
  }
  p[11] = 0x04;  // line tracer off, speed code 4 (API speed 5)
  p[12] = 0x02;  // proximity IR current
  p[13] = 0x03;  // gravity range 0, bandwidth 3
  return p;
}

std::optional<Effector> decodeEffector(Model model, const Payload& p, std::string* why) {
  Effector e;
  if (model == Model::HamsterS) {
    if ((p[0] >> 4) != 1) {
      setWhy(why, (p[0] >> 4) == 2 ? "serial pass-through packet" : "not a Hamster-S motoring packet (type nibble)");
      return std::nullopt;
    }
    e.left_wheel = static_cast<int8_t>(p[1]);
    e.right_wheel = static_cast<int8_t>(p[2]);
    for (size_t i = 0; i < 3; ++i) {
      e.left_led_rgb[i] = p[3 + i];
      e.right_led_rgb[i] = p[6 + i];
    }
    if (p[18] == 0x01) {
      e.note = p[19];
    } else if (p[18] != 0x00) {
      const int v = readU16(p, 18) - 512;
      e.buzzer_hz = v > 0 ? v / 10.0 : 0.0;
    }
    return e;
  }
  if (p[2] != 0x10) {
    setWhy(why, "not a Hamster motoring command (byte 2 is not 0x10)");
    return std::nullopt;
  }
  e.left_wheel = static_cast<int8_t>(p[3]);
  e.right_wheel = static_cast<int8_t>(p[4]);
  e.left_led_rgb = colourRgb(p[5] & 7);
  e.right_led_rgb = colourRgb(p[6] & 7);
  e.buzzer_hz = (static_cast<uint32_t>(p[7]) << 16 | static_cast<uint32_t>(p[8]) << 8 | p[9]) / 100.0;
  e.note = p[10];
  return e;
}

std::string encodeLine(const Payload& payload, const Address& address) {
  std::string out;
  out.reserve(kDataLineChars + 1);
  for (uint8_t b : payload) appendHex(out, b);
  out += '-';
  out += address.wire();
  out += '\r';
  return out;
}

std::optional<Sensors> decodeSensors(Model model, const Payload& p, std::string* why) {
  Sensors s;
  s.model = model;
  if (model == Model::HamsterS) {
    const int type = p[0] >> 4;
    if (type != 1) {
      setWhy(why, type == 2 ? "serial pass-through packet"
                            : "not a Hamster-S sensor packet (type nibble " + std::to_string(type) + ")");
      return std::nullopt;
    }
    s.has_pulse_count = true;
    s.pulse_count = readU16(p, 1);
    s.proximity_left = p[3];
    s.proximity_right = p[4];
    if (p[19] & 0x01) {
      s.has_temperature = true;
      s.temperature_c = static_cast<int8_t>(p[5]) / 2.0 + 23.0;
      s.has_battery = true;
      s.battery_v = 2.0 + p[6] / 100.0;
    } else {
      s.has_light = true;
      s.light = readU16(p, 5);
    }
    s.floor_left = p[7];
    s.floor_right = p[8];
    s.accel_x = readS16(p, 9);
    s.accel_y = readS16(p, 11);
    s.accel_z = readS16(p, 13);
    s.input_a = p[15];
    s.input_b = p[16];
    s.rssi_dbm = static_cast<int8_t>(p[18]);
    return s;
  }
  if ((p[2] >> 4) != 1) {
    setWhy(why, "not a Hamster sensor packet (command echo nibble " + std::to_string(p[2] >> 4) + ", expected 1)");
    return std::nullopt;
  }
  s.model = Model::Hamster;
  s.rssi_dbm = static_cast<int8_t>(p[3]);
  s.proximity_left = p[4];
  s.proximity_right = p[5];
  s.floor_left = p[6];
  s.floor_right = p[7];
  s.accel_x = readS16(p, 8);
  s.accel_y = readS16(p, 10);
  s.accel_z = readS16(p, 12);
  if (p[14] == 0) {
    s.has_light = true;
    s.light = readU16(p, 15);
  } else {
    s.has_temperature = true;
    s.temperature_c = static_cast<int8_t>(p[15]) / 2.0 + 24.0;
    s.has_battery = true;
    s.battery_v = 2.0 + p[16] / 100.0;
  }
  s.input_a = p[17];
  s.input_b = p[18];
  return s;
}

Payload encodeSensors(Model model, const Sensors& s, bool light_packet) {
  Payload p{};
  auto writeS16 = [&p](size_t i, int16_t v) { writeU16(p, i, static_cast<uint16_t>(v)); };
  const long temp_offset = model == Model::HamsterS ? 23 : 24;
  const auto temp_raw = static_cast<uint8_t>(static_cast<int8_t>(
      clampByte(std::lround((s.temperature_c - static_cast<double>(temp_offset)) * 2.0) + 128, 0, 255) - 128));
  const uint8_t battery_raw = clampByte(std::lround((s.battery_v - 2.0) * 100.0), 0, 255);
  if (model == Model::HamsterS) {
    p[0] = 0x10;
    writeU16(p, 1, s.pulse_count);
    p[3] = s.proximity_left;
    p[4] = s.proximity_right;
    if (light_packet) {
      writeU16(p, 5, s.light);
    } else {
      p[5] = temp_raw;
      p[6] = battery_raw;
      p[19] |= 0x01;
    }
    p[7] = s.floor_left;
    p[8] = s.floor_right;
    writeS16(9, s.accel_x);
    writeS16(11, s.accel_y);
    writeS16(13, s.accel_z);
    p[15] = s.input_a;
    p[16] = s.input_b;
    p[18] = static_cast<uint8_t>(s.rssi_dbm);
    return p;
  }
  p[2] = 0x10;
  p[3] = static_cast<uint8_t>(s.rssi_dbm);
  p[4] = s.proximity_left;
  p[5] = s.proximity_right;
  p[6] = s.floor_left;
  p[7] = s.floor_right;
  writeS16(8, s.accel_x);
  writeS16(10, s.accel_y);
  writeS16(12, s.accel_z);
  if (light_packet) {
    writeU16(p, 15, s.light);
  } else {
    p[14] = 1;
    p[15] = temp_raw;
    p[16] = battery_raw;
  }
  p[17] = s.input_a;
  p[18] = s.input_b;
  return p;
}

std::string hexBytes(const uint8_t* data, size_t size) {
  std::string out;
  out.reserve(2 * size);
  for (size_t i = 0; i < size; ++i) appendHex(out, data[i]);
  return out;
}

std::string encodeIdentifyReply(const IdentifyReply& r) {
  std::string out = "FF," + r.name + ",";
  appendHex(out, r.model_code);
  out += "," + r.info + "," + r.address.wire();
  return out;
}

ParsedLine parseLine(std::string_view line) {
  ParsedLine out;
  if (line.size() == 1) {
    out.kind = LineKind::NoRobot;
    return out;
  }
  if (line.size() >= 3 && line[0] == 'F' && line[1] == 'F' && line[2] == ',') {
    std::vector<std::string_view> fields;
    size_t start = 0;
    while (fields.size() < 16) {
      const size_t comma = line.find(',', start);
      fields.push_back(line.substr(start, comma == std::string_view::npos ? std::string_view::npos : comma - start));
      if (comma == std::string_view::npos) break;
      start = comma + 1;
    }
    if (fields.size() < 5) {
      out.error = "FF reply has " + std::to_string(fields.size()) + " fields, expected at least 5";
      return out;
    }
    uint8_t code = 0;
    if (fields[2].size() != 2 || parseHexBytes(fields[2], &code, 1) >= 0) {
      out.error = "FF reply: model code '" + std::string(fields[2]) + "' is not 2 hex digits";
      return out;
    }
    const auto address = fields[4].size() == 12 ? Address::parse(fields[4]) : std::nullopt;
    if (!address) {
      out.error = "FF reply: address '" + std::string(fields[4].substr(0, 32)) + "' is not 12 hex digits";
      return out;
    }
    out.kind = LineKind::Identify;
    out.identify.name = std::string(fields[1]);
    out.identify.model_code = code;
    out.identify.model = code == 0x04 ? Model::Hamster : code == 0x0E ? Model::HamsterS : Model::Unknown;
    out.identify.info = std::string(fields[3]);
    out.identify.address = *address;
    return out;
  }
  if (line.size() != kDataLineChars) {
    out.error = "line has " + std::to_string(line.size()) + " characters, expected 53 (data line)";
    return out;
  }
  const int bad_payload = parseHexBytes(line, out.payload.data(), kPayloadBytes);
  if (bad_payload >= 0) {
    out.error = "non-hex character in payload at column " + std::to_string(bad_payload + 1);
    return out;
  }
  if (line[40] != '-') {
    out.error = "expected '-' at column 41";
    return out;
  }
  const int bad_address = parseHexBytes(line.substr(41), out.address.bytes.data(), 6);
  if (bad_address >= 0) {
    out.error = "non-hex character in address at column " + std::to_string(42 + bad_address);
    return out;
  }
  out.kind = LineKind::Data;
  return out;
}

}  // namespace ddace::hamster
