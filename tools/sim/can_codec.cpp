#include "can_codec.hpp"

#include <cmath>
#include <cstdio>
#include <cstring>

namespace torqued::sim {

namespace {

// ENGINE_1 0x100, Intel (little-endian), 100 Hz.
constexpr SignalDef kEngine1[] = {
    {"EngineSpeed", 0, 16, true, false, 0.25, 0.0, 0.0, 16383.75, "rpm"},
    {"MAP", 16, 16, true, false, 0.01, 0.0, 0.0, 655.35, "kPa"},
    {"IntakeAirTemp", 32, 8, true, false, 1.0, -40.0, -40.0, 215.0, "degC"},
    {"Throttle", 40, 16, true, false, 0.01, 0.0, 0.0, 100.0, "%"},
};
// ENGINE_2 0x101, Motorola (big-endian) to exercise both byte orders.
constexpr SignalDef kEngine2[] = {
    {"MAF", 7, 16, false, false, 0.01, 0.0, 0.0, 655.35, "g/s"},
    {"FuelMass", 23, 16, false, false, 0.001, 0.0, 0.0, 65.535, "mg"},
    {"SparkAdvance", 39, 8, false, true, 0.5, 0.0, -64.0, 63.5, "deg"},
    {"Lambda", 47, 16, false, false, 0.0001, 0.0, 0.0, 6.5535, ""},
    {"FuelCutoff", 63, 1, false, false, 1.0, 0.0, 0.0, 1.0, ""},
};
// ENGINE_3 0x102, Intel, DLC 4.
constexpr SignalDef kEngine3[] = {
    {"OilTemp", 0, 16, true, true, 0.1, 0.0, -40.0, 200.0, "degC"},
    {"CoolantTemp", 16, 16, true, true, 0.1, 0.0, -40.0, 200.0, "degC"},
};
// DYNO_1 0x200, Intel.
constexpr SignalDef kDyno1[] = {
    {"LoadTorque", 0, 16, true, true, 0.1, 0.0, -3276.8, 3276.7, "Nm"},
    {"DynoSpeed", 16, 16, true, false, 0.25, 0.0, 0.0, 16383.75, "rpm"},
};

// EM_1 0x210, Intel: the electric machine on the crankshaft (hybrid input). Sent only by scenarios with a
// machine.
constexpr SignalDef kEm1[] = {
    {"EmTorque", 0, 16, true, true, 0.1, 0.0, -3276.8, 3276.7, "Nm"},
    {"EmSpeed", 16, 16, true, false, 0.5, 0.0, 0.0, 32767.5, "rpm"},
};

// VEH_1 0x220, Intel: driveline state of a vehicle scenario (clutch open: the engine drives no wheels). Sent
// only by scenarios with a vehicle driveline (engine_sim.hpp VehicleSim).
constexpr SignalDef kVeh1[] = {
    {"ClutchOpen", 0, 1, true, false, 1.0, 0.0, 0.0, 1.0, ""},
};

constexpr MessageDef kMessages[] = {
    {"ENGINE_1", kEngine1Id, 8, "ECU", "Engine speed and air path, 100 Hz", kEngine1},
    {"ENGINE_2", kEngine2Id, 8, "ECU", "Fuel and ignition (Motorola byte order), 100 Hz", kEngine2},
    {"ENGINE_3", kEngine3Id, 4, "ECU", "Temperatures, 100 Hz", kEngine3},
    {"DYNO_1", kDyno1Id, 8, "DYNO", "Dynamometer torque flange and speed, 100 Hz", kDyno1},
    {"EM_1", kEm1Id, 4, "EM", "Electric machine on the crankshaft (hybrid), 100 Hz", kEm1},
    {"VEH_1", kVeh1Id, 1, "TCU", "Driveline state (clutch open), 100 Hz", kVeh1},
};

/// Byte/bit position of the k-th bit counted from the LSB of the raw value.
void bit_positions(const SignalDef& sig, int* pos) noexcept {
  if (sig.little_endian) {
    for (int i = 0; i < sig.length; ++i) pos[i] = sig.start_bit + i;
    return;
  }
  // Motorola: start bit is the MSB; walk towards the LSB in DBC sawtooth numbering.
  int p = sig.start_bit;
  for (int i = sig.length - 1; i >= 0; --i) {
    pos[i] = p;
    p = (p % 8 == 0) ? p + 15 : p - 1;
  }
}

std::string fmt_num(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

}  // namespace

std::span<const MessageDef> demo_messages() noexcept { return kMessages; }

const MessageDef* find_message(std::uint32_t id) noexcept {
  for (const auto& m : kMessages)
    if (m.id == id) return &m;
  return nullptr;
}

const SignalDef* find_signal(const MessageDef& msg, const char* name) noexcept {
  for (const auto& s : msg.signals)
    if (std::strcmp(s.name, name) == 0) return &s;
  return nullptr;
}

void pack_signal(const SignalDef& sig, double value, std::uint8_t* data) noexcept {
  const double scaled = std::round((value - sig.offset) / sig.factor);
  const double lo = sig.is_signed ? -std::ldexp(1.0, sig.length - 1) : 0.0;
  const double hi = sig.is_signed ? std::ldexp(1.0, sig.length - 1) - 1.0 : std::ldexp(1.0, sig.length) - 1.0;
  double r = std::isfinite(scaled) ? scaled : 0.0;
  if (r < lo) r = lo;
  if (r > hi) r = hi;
  const auto raw = static_cast<std::uint64_t>(static_cast<std::int64_t>(r));  // two's complement for signed
  int pos[64];
  bit_positions(sig, pos);
  for (int i = 0; i < sig.length; ++i) {
    const int byte = pos[i] / 8;
    const int bit = pos[i] % 8;
    if ((raw >> i) & 1u)
      data[byte] = static_cast<std::uint8_t>(data[byte] | (1u << bit));
    else
      data[byte] = static_cast<std::uint8_t>(data[byte] & ~(1u << bit));
  }
}

double unpack_signal(const SignalDef& sig, const std::uint8_t* data) noexcept {
  int pos[64];
  bit_positions(sig, pos);
  std::uint64_t raw = 0;
  for (int i = 0; i < sig.length; ++i) {
    if ((data[pos[i] / 8] >> (pos[i] % 8)) & 1u) raw |= (std::uint64_t{1} << i);
  }
  double v = static_cast<double>(raw);
  if (sig.is_signed && ((raw >> (sig.length - 1)) & 1u)) v -= std::ldexp(1.0, sig.length);
  return v * sig.factor + sig.offset;
}

std::string demo_dbc_text() {
  std::string s;
  s += "VERSION \"torqued-demo 1.0\"\n\n\n";
  s += "NS_ :\n\tNS_DESC_\n\tCM_\n\tBA_DEF_\n\tBA_\n\tVAL_\n\tCAT_DEF_\n\tCAT_\n\tFILTER\n\tBA_DEF_DEF_\n"
       "\tEV_DATA_\n\tENVVAR_DATA_\n\tSGTYPE_\n\tSGTYPE_VAL_\n\tBA_DEF_SGTYPE_\n\tBA_SGTYPE_\n\tSIG_TYPE_REF_"
       "\n"
       "\tVAL_TABLE_\n\tSIG_GROUP_\n\tSIG_VALTYPE_\n\tSIGTYPE_VALTYPE_\n\tBO_TX_BU_\n\tBA_DEF_REL_\n\tBA_REL_"
       "\n"
       "\tBA_DEF_DEF_REL_\n\tBU_SG_REL_\n\tBU_EV_REL_\n\tBU_BO_REL_\n\tSG_MUL_VAL_\n\n";
  s += "BS_:\n\n";
  s += "BU_: ECU DYNO EM TCU TORQUED\n\n\n";
  for (const auto& m : kMessages) {
    s += "BO_ " + std::to_string(m.id) + " " + m.name + ": " + std::to_string(m.dlc) + " " + m.sender + "\n";
    for (const auto& g : m.signals) {
      s += std::string(" SG_ ") + g.name + " : " + std::to_string(g.start_bit) + "|" +
           std::to_string(g.length) + "@" + (g.little_endian ? "1" : "0") + (g.is_signed ? "-" : "+") + " (" +
           fmt_num(g.factor) + "," + fmt_num(g.offset) + ") [" + fmt_num(g.min) + "|" + fmt_num(g.max) +
           "] \"" + g.unit + "\" TORQUED\n";
    }
    s += "\n";
  }
  s += "\n";
  s += "CM_ \"Demo CAN database of the torqued engine simulator (tools/sim); generated by torque-sim "
       "--write-dbc.\";\n";
  s += "CM_ BU_ ECU \"Engine control unit\";\n";
  s += "CM_ BU_ DYNO \"Test-bench dynamometer\";\n";
  s += "CM_ BU_ EM \"Electric machine inverter (hybrid)\";\n";
  s += "CM_ BU_ TCU \"Transmission control unit (vehicle driveline)\";\n";
  for (const auto& m : kMessages) {
    s += "CM_ BO_ " + std::to_string(m.id) + " \"" + m.comment + "\";\n";
  }
  s += "CM_ SG_ 257 FuelMass \"Fuel mass per injection per cylinder\";\n";
  s += "CM_ SG_ 257 FuelCutoff \"1 = overrun fuel cut-off active\";\n";
  s += "CM_ SG_ 512 LoadTorque \"Torque absorbed by the dynamometer; negative when motoring\";\n";
  s += "CM_ SG_ 528 EmTorque \"Machine shaft torque; positive when it drives the crankshaft, negative when "
       "generating\";\n";
  s += "CM_ SG_ 544 ClutchOpen \"1 = clutch open: the engine drives no wheels\";\n";
  s += "BA_DEF_ BO_ \"GenMsgCycleTime\" INT 0 65535;\n";
  s += "BA_DEF_ BO_ \"GenMsgSendType\" ENUM  \"Cyclic\",\"Event\";\n";
  s += "BA_DEF_  \"BusType\" STRING ;\n";
  s += "BA_DEF_  \"DBName\" STRING ;\n";
  s += "BA_DEF_DEF_  \"GenMsgCycleTime\" 0;\n";
  s += "BA_DEF_DEF_  \"GenMsgSendType\" \"Cyclic\";\n";
  s += "BA_DEF_DEF_  \"BusType\" \"CAN\";\n";
  s += "BA_DEF_DEF_  \"DBName\" \"\";\n";
  s += "BA_ \"BusType\" \"CAN\";\n";
  s += "BA_ \"DBName\" \"torqued_demo\";\n";
  for (const auto& m : kMessages) {
    s += "BA_ \"GenMsgCycleTime\" BO_ " + std::to_string(m.id) + " 10;\n";
  }
  s += "VAL_ 257 FuelCutoff 1 \"Active\" 0 \"Inactive\" ;\n";
  return s;
}

}  // namespace torqued::sim
