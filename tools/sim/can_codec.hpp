#pragma once
// The simulator's CAN message set (docs/simulator.md §5, CAN) as data: one table drives the frame packing,
// the decoding used by signals_at() and the text of config/demo.dbc, so the three cannot disagree.
#include <array>
#include <cstdint>
#include <span>
#include <string>

namespace torqued::sim {

/// One DBC signal (SG_). Bit numbering as in DBC: Intel start bit = LSB, Motorola start bit = MSB (sawtooth).
struct SignalDef {
  const char* name;
  int start_bit;
  int length;
  bool little_endian;  ///< @1 (Intel) when true, @0 (Motorola) when false
  bool is_signed;
  double factor;
  double offset;
  double min;
  double max;
  const char* unit;
};

struct MessageDef {
  const char* name;
  std::uint32_t id;
  int dlc;
  const char* sender;
  const char* comment;
  std::span<const SignalDef> signals;
};

/// Message ids of the demo set.
inline constexpr std::uint32_t kEngine1Id = 0x100;
inline constexpr std::uint32_t kEngine2Id = 0x101;
inline constexpr std::uint32_t kEngine3Id = 0x102;
inline constexpr std::uint32_t kDyno1Id = 0x200;
inline constexpr std::uint32_t kEm1Id = 0x210;  ///< electric machine (hybrid input)
inline constexpr std::uint32_t kVeh1Id =
    0x220;  ///< vehicle driveline flags (clutch open); last in demo_messages()

[[nodiscard]] std::span<const MessageDef> demo_messages() noexcept;
[[nodiscard]] const MessageDef* find_message(std::uint32_t id) noexcept;
[[nodiscard]] const SignalDef* find_signal(const MessageDef& msg, const char* name) noexcept;

/// Physical value -> raw (rounded, saturated to the raw range) written into `data`.
void pack_signal(const SignalDef& sig, double value, std::uint8_t* data) noexcept;
/// Raw bits of `data` -> physical value.
[[nodiscard]] double unpack_signal(const SignalDef& sig, const std::uint8_t* data) noexcept;

/// Full text of config/demo.dbc (VERSION, NS_, BS_, BU_, BO_/SG_, CM_, BA_DEF_, BA_DEF_DEF_, BA_, VAL_).
[[nodiscard]] std::string demo_dbc_text();

}  // namespace torqued::sim
