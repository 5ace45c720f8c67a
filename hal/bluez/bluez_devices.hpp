// `locus devices` for BlueZ: the Bluetooth adapters bluetoothd offers on the system bus.
//
// Why a synchronous one-shot query (not the scanner's loop): listing runs once from the CLI, before
// anything else; a short call timeout keeps a hung bluetoothd from hanging the tool. Never throws:
// no system bus, no bluetoothd or a failing call give one entry of kind "unavailable" saying why.
#pragma once

#include <vector>

#include "devices.hpp"

namespace locus::hal {

/// [main] One entry per org.bluez.Adapter1 (backend "bluez", kind "adapter", id "hci0", description
/// "address 00:11:22:33:44:55, name 'host', powered, not discovering"), sorted by id; one entry of
/// kind "unavailable" when the bus or bluetoothd cannot be reached or bluetoothd has no adapter.
/// `timeout_s` bounds the D-Bus call.
std::vector<DeviceInfo> list_bluez_adapters(double timeout_s = 2.0);

}  // namespace locus::hal
