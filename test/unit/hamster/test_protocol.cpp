// The wire format: payload layouts of both models, framing, FF replies, reassembly.
#include <gtest/gtest.h>

#include <string>

#include "ddace/hamster/protocol.h"

using namespace ddace::hamster;

namespace {

std::string hex(const Payload& p) {
  static const char* d = "0123456789ABCDEF";
  std::string s;
  for (uint8_t b : p) {
    s += d[b >> 4];
    s += d[b & 15];
  }
  return s;
}

std::string noSpaces(std::string s) {
  s.erase(std::remove(s.begin(), s.end(), ' '), s.end());
  return s;
}

Payload fromHex(const std::string& h) {
  Payload p{};
  for (size_t i = 0; i < p.size(); ++i) p[i] = static_cast<uint8_t>(std::stoi(h.substr(2 * i, 2), nullptr, 16));
  return p;
}

const Address kAddress = *Address::parse("67E1A48B4BD9");

}  // namespace

TEST(HamsterProtocol, AddressWireAndDisplayFormsAreByteReversed) {
  EXPECT_EQ(kAddress.wire(), "67E1A48B4BD9");
  EXPECT_EQ(kAddress.display(), "D9:4B:8B:A4:E1:67");
  auto colon = Address::parse("d9:4b:8b:a4:e1:67");
  ASSERT_TRUE(colon);
  EXPECT_EQ(*colon, kAddress);
  EXPECT_FALSE(Address::parse("67E1A48B4BD"));
  EXPECT_FALSE(Address::parse("67E1A48B4BDG"));
  EXPECT_FALSE(Address::parse("D9-4B:8B:A4:E1:67"));
}

TEST(HamsterProtocol, HamsterEffectorMatchesTheDocumentedExample) {
  Effector e;
  e.left_wheel = 50;
  e.right_wheel = -50;
  EXPECT_EQ(hex(encodeEffector(Model::Hamster, e)),
            noSpaces("00 00 10 32 CE 00 00 000000 00 04 02 03 00 00 00 00 00 00"));
}

TEST(HamsterProtocol, HamsterSEffectorMatchesTheDocumentedExample) {
  Effector e;
  e.left_wheel = 30;
  e.right_wheel = 30;
  EXPECT_EQ(hex(encodeEffector(Model::HamsterS, e)), noSpaces("10 1E 1E 000000 000000 00 0000 00 54 40 00 00 00 0200"));
}

TEST(HamsterProtocol, WheelsAreClampedToPlusMinus100) {
  Effector e;
  e.left_wheel = 120;
  e.right_wheel = -128;
  const Payload p = encodeEffector(Model::Hamster, e);
  EXPECT_EQ(static_cast<int8_t>(p[3]), 100);
  EXPECT_EQ(static_cast<int8_t>(p[4]), -100);
}

TEST(HamsterProtocol, LedsAndSound) {
  Effector e;
  e.left_led_rgb = {255, 0, 0};     // red
  e.right_led_rgb = {0, 200, 255};  // cyan = green + blue
  e.buzzer_hz = 440.0;
  Payload p = encodeEffector(Model::Hamster, e);
  EXPECT_EQ(p[5], 4);
  EXPECT_EQ(p[6], 3);
  EXPECT_EQ(hex(p).substr(14, 6), "00ABE0");  // 440 Hz * 100 = 44000
  p = encodeEffector(Model::HamsterS, e);
  EXPECT_EQ(p[3], 255);
  EXPECT_EQ(p[7], 200);
  EXPECT_EQ(hex(p).substr(36, 4), "1330");  // 440 * 10 + 512 = 4912
  e.note = 49;                              // a note wins over the buzzer
  EXPECT_EQ(hex(encodeEffector(Model::HamsterS, e)).substr(36, 4), "0131");
  p = encodeEffector(Model::Hamster, e);
  EXPECT_EQ(p[10], 49);
  EXPECT_EQ(hex(p).substr(14, 6), "000000");
  // And the mock's decoder reads them back.
  const auto back = decodeEffector(Model::Hamster, encodeEffector(Model::Hamster, e));
  ASSERT_TRUE(back);
  EXPECT_EQ(back->note, 49);
  EXPECT_EQ(back->right_led_rgb, (std::array<uint8_t, 3>{0, 255, 255}));
}

TEST(HamsterProtocol, LineFramingIs54Characters) {
  const std::string line = encodeLine(encodeEffector(Model::Hamster, Effector{}), kAddress);
  ASSERT_EQ(line.size(), 54u);
  EXPECT_EQ(line[40], '-');
  EXPECT_EQ(line.substr(41, 12), "67E1A48B4BD9");
  EXPECT_EQ(line.back(), '\r');
  const ParsedLine parsed = parseLine(std::string_view(line).substr(0, 53));
  ASSERT_EQ(parsed.kind, LineKind::Data) << parsed.error;
  EXPECT_EQ(parsed.address, kAddress);
}

TEST(HamsterProtocol, DecodesAHandBuiltHamsterSensorPayload) {
  // rssi 0xC4 = -60 dBm; prox 10/20; floor 30/40; accel x = -2 (FFFE), y = 256, z = 16384;
  // flag 1 → temperature raw 2 → 25 °C, battery raw 190 → 3.90 V; inputs 7/8.
  const Payload p = fromHex(noSpaces("00 00 10 C4 0A 14 1E 28 FFFE 0100 4000 01 02 BE 07 08 00"));
  std::string why;
  const auto s = decodeSensors(Model::Hamster, p, &why);
  ASSERT_TRUE(s) << why;
  EXPECT_EQ(s->rssi_dbm, -60);
  EXPECT_EQ(s->proximity_left, 10);
  EXPECT_EQ(s->proximity_right, 20);
  EXPECT_EQ(s->floor_left, 30);
  EXPECT_EQ(s->floor_right, 40);
  EXPECT_EQ(s->accel_x, -2);
  EXPECT_EQ(s->accel_y, 256);
  EXPECT_EQ(s->accel_z, 16384);
  EXPECT_TRUE(s->has_temperature);
  EXPECT_DOUBLE_EQ(s->temperature_c, 25.0);
  EXPECT_TRUE(s->has_battery);
  EXPECT_NEAR(s->battery_v, 3.90, 1e-9);
  EXPECT_FALSE(s->has_light);
  EXPECT_EQ(s->input_a, 7);
  EXPECT_EQ(s->input_b, 8);
  // Flag 0: the same bytes are the light level.
  Payload q = p;
  q[14] = 0;
  const auto l = decodeSensors(Model::Hamster, q);
  ASSERT_TRUE(l);
  EXPECT_TRUE(l->has_light);
  EXPECT_EQ(l->light, 0x02BE);
  EXPECT_FALSE(l->has_battery);
}

TEST(HamsterProtocol, DecodesAHandBuiltHamsterSSensorPayload) {
  // type 1; pulses 0x0102; prox 5/6; temp raw -4 → 21 °C, battery raw 150 → 3.5 V;
  // floor 7/8; accel 1,-1,2; inputs 9/10; events 0; rssi -70 (BA); status bit 0 = 1.
  const Payload p = fromHex(noSpaces("10 0102 05 06 FC 96 07 08 0001 FFFF 0002 09 0A 00 BA 01"));
  const auto s = decodeSensors(Model::HamsterS, p);
  ASSERT_TRUE(s);
  EXPECT_EQ(s->pulse_count, 0x0102);
  EXPECT_EQ(s->proximity_left, 5);
  EXPECT_EQ(s->floor_right, 8);
  EXPECT_EQ(s->accel_y, -1);
  EXPECT_DOUBLE_EQ(s->temperature_c, 21.0);
  EXPECT_NEAR(s->battery_v, 3.5, 1e-9);
  EXPECT_EQ(s->rssi_dbm, -70);
  EXPECT_EQ(s->input_b, 10);
}

TEST(HamsterProtocol, RefusesPacketsOfTheWrongType) {
  std::string why;
  Payload p{};  // Hamster: byte 2 high nibble 0
  EXPECT_FALSE(decodeSensors(Model::Hamster, p, &why));
  EXPECT_NE(why.find("command echo"), std::string::npos);
  p[0] = 0x21;  // Hamster-S serial pass-through
  EXPECT_FALSE(decodeSensors(Model::HamsterS, p, &why));
  EXPECT_EQ(why, "serial pass-through packet");
}

TEST(HamsterProtocol, SensorEncodeDecodeRoundTripsForBothModels) {
  for (Model m : {Model::Hamster, Model::HamsterS}) {
    for (bool light : {true, false}) {
      Sensors s;
      s.proximity_left = 1;
      s.proximity_right = 255;
      s.floor_left = 128;
      s.floor_right = 3;
      s.accel_x = -32768;
      s.accel_y = 32767;
      s.accel_z = -1;
      s.rssi_dbm = -128;
      s.light = 65535;
      s.temperature_c = 30.5;
      s.battery_v = 4.2;
      s.pulse_count = 999;
      const auto d = decodeSensors(m, encodeSensors(m, s, light));
      ASSERT_TRUE(d);
      EXPECT_EQ(d->proximity_right, 255);
      EXPECT_EQ(d->accel_x, -32768);
      EXPECT_EQ(d->accel_y, 32767);
      EXPECT_EQ(d->rssi_dbm, -128);
      EXPECT_EQ(d->has_light, light);
      if (light) {
        EXPECT_EQ(d->light, 65535);
      } else {
        EXPECT_DOUBLE_EQ(d->temperature_c, 30.5);
        EXPECT_NEAR(d->battery_v, 4.2, 1e-9);
      }
      EXPECT_EQ(d->has_pulse_count, m == Model::HamsterS);
    }
  }
}

TEST(HamsterProtocol, ParsesTheIdentifyReply) {
  const ParsedLine p = parseLine("FF,Hamster,04,05,67E1A48B4BD9");
  ASSERT_EQ(p.kind, LineKind::Identify) << p.error;
  EXPECT_EQ(p.identify.name, "Hamster");
  EXPECT_EQ(p.identify.model, Model::Hamster);
  EXPECT_EQ(p.identify.info, "05");
  EXPECT_EQ(p.identify.address, kAddress);
  EXPECT_EQ(parseLine("FF,HamsterS,0E,01,67E1A48B4BD9").identify.model, Model::HamsterS);
  const ParsedLine other = parseLine("FF,Cheese,0D,01,67E1A48B4BD9");
  ASSERT_EQ(other.kind, LineKind::Identify);
  EXPECT_EQ(other.identify.model, Model::Unknown);
  EXPECT_EQ(other.identify.model_code, 0x0D);
  IdentifyReply r;
  r.name = "Hamster";
  r.model_code = 4;
  r.info = "05";
  r.address = kAddress;
  EXPECT_EQ(encodeIdentifyReply(r), "FF,Hamster,04,05,67E1A48B4BD9");
}

TEST(HamsterProtocol, MalformedLinesSayWhatIsWrongAndWhere) {
  EXPECT_EQ(parseLine("0").kind, LineKind::NoRobot);
  const std::string good = encodeLine(encodeEffector(Model::Hamster, Effector{}), kAddress).substr(0, 53);
  std::string bad = good;
  bad[7] = 'G';
  ParsedLine p = parseLine(bad);
  EXPECT_EQ(p.kind, LineKind::Malformed);
  EXPECT_EQ(p.error, "non-hex character in payload at column 8");
  bad = good;
  bad[40] = '+';
  EXPECT_EQ(parseLine(bad).error, "expected '-' at column 41");
  bad = good;
  bad[50] = 'z';
  EXPECT_EQ(parseLine(bad).error, "non-hex character in address at column 51");
  EXPECT_EQ(parseLine(good.substr(0, 30)).error, "line has 30 characters, expected 53 (data line)");
  EXPECT_EQ(parseLine("FF,Hamster,04").kind, LineKind::Malformed);
  EXPECT_NE(parseLine("FF,Hamster,4,01,67E1A48B4BD9").error.find("model code"), std::string::npos);
  EXPECT_NE(parseLine("FF,Hamster,04,01,67E1A48B4B").error.find("address"), std::string::npos);
  // Lower-case hex is still hex.
  std::string lower = good;
  std::transform(lower.begin(), lower.end(), lower.begin(), [](char c) { return std::tolower(c); });
  EXPECT_EQ(parseLine(lower).kind, LineKind::Data);
}

TEST(HamsterProtocol, AssemblerSplitsAStreamAtAnyChunkBoundary) {
  const std::string a = encodeLine(encodeEffector(Model::Hamster, Effector{}), kAddress);
  const std::string stream = a + "0\r" + "FF,Hamster,04,01,67E1A48B4BD9\r\n" + a;
  for (size_t chunk = 1; chunk <= stream.size(); ++chunk) {
    LineAssembler as;
    std::vector<std::string> lines;
    for (size_t i = 0; i < stream.size(); i += chunk) {
      as.push(stream.data() + i, std::min(chunk, stream.size() - i),
              [&](std::string_view l) { lines.emplace_back(l); });
    }
    ASSERT_EQ(lines.size(), 4u) << "chunk " << chunk;
    EXPECT_EQ(lines[0], a.substr(0, 53));
    EXPECT_EQ(lines[1], "0");
    EXPECT_EQ(lines[2].substr(0, 3), "FF,");
    EXPECT_EQ(lines[3], a.substr(0, 53));
    EXPECT_EQ(as.pending(), 0u);
  }
}

TEST(HamsterProtocol, AssemblerDropsOverlongLinesAndRecovers) {
  LineAssembler as;
  std::vector<std::string> lines;
  const std::string junk(1000, 'A');
  const std::string good = encodeLine(encodeEffector(Model::Hamster, Effector{}), kAddress);
  const std::string stream = junk + "\r" + good;
  as.push(stream.data(), stream.size(), [&](std::string_view l) { lines.emplace_back(l); });
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_EQ(lines[0], good.substr(0, 53));
  EXPECT_EQ(as.overlong(), 1u);
}
