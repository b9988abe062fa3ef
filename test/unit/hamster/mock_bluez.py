#!/usr/bin/python3
"""A mock BlueZ for the BLE transport test (test_ble.cpp): the org.bluez D-Bus objects
and behaviour that ddace::hamster::BleTransport uses, on the bus named by
DBUS_SYSTEM_BUS_ADDRESS (a private dbus-daemon started by the test). No radio.

    mock_bluez.py --address D9:4B:8B:A4:E1:67 [--adapter hci0] [--connect-delay 0.3]

- one adapter (Adapter1: StartDiscovery/StopDiscovery/SetDiscoveryFilter);
- one original Hamster (Device1: Connect/Disconnect) that BlueZ does not know until
  discovery has run (InterfacesAdded 0.2 s after StartDiscovery). Connect answers
  after --connect-delay s; the GATT services (sensor 00009001/0000900a, notify;
  effector 0000a000/0000a006, write) appear 50 ms later, then ServicesResolved.
  A disconnect removes them again, as BlueZ does;
- while notifying, a sensor notification (PropertiesChanged "Value") every 20 ms.

Control, for the test: org.ddace.MockBluez at /org/ddace/mock:
    SetSensor(ay)  payload streamed from now on     Notify(ay)  one extra notification
    Drop()         the radio link breaks (Connected=false, GATT objects removed)
    Stall(b)       stop / resume notifications       Vanish()    BlueZ forgets the device (objects removed)
    Writes() -> a(uays)  every WriteValue: (connection number, bytes, options["type"])
    Calls() -> as        every BlueZ method called, in order
Prints "ready" on stdout once it owns org.bluez.
"""
import argparse
import os
import sys

import dbus
import dbus.mainloop.glib
import dbus.service
from gi.repository import GLib

BLUEZ = "org.bluez"
OM = "org.freedesktop.DBus.ObjectManager"
PROPS = "org.freedesktop.DBus.Properties"
ADAPTER = "org.bluez.Adapter1"
DEVICE = "org.bluez.Device1"
SERVICE = "org.bluez.GattService1"
CHAR = "org.bluez.GattCharacteristic1"
CONTROL = "org.ddace.MockBluez"
SENSOR_SERVICE = "00009001-9c80-11e3-a5e2-0800200c9a66"
SENSOR_CHAR = "0000900a-9c80-11e3-a5e2-0800200c9a66"
EFFECTOR_SERVICE = "0000a000-9c80-11e3-a5e2-0800200c9a66"
EFFECTOR_CHAR = "0000a006-9c80-11e3-a5e2-0800200c9a66"


class BluezError(dbus.DBusException):
    def __init__(self, name, message):
        super().__init__(message)
        self._dbus_error_name = "org.bluez.Error." + name


class PropertyObject(dbus.service.Object):
    """An exported object with one BlueZ interface and org.freedesktop.DBus.Properties."""

    def __init__(self, mock, path, iface, props):
        self.mock, self.path, self.iface, self.props = mock, path, iface, props
        super().__init__(mock.bus, path)

    def set(self, **changes):
        self.props.update(changes)
        self.PropertiesChanged(self.iface, dbus.Dictionary(changes, signature="sv"), dbus.Array([], signature="s"))

    @dbus.service.method(PROPS, in_signature="ss", out_signature="v")
    def Get(self, iface, name):
        return self.props[name]

    @dbus.service.method(PROPS, in_signature="s", out_signature="a{sv}")
    def GetAll(self, iface):
        return dbus.Dictionary(self.props, signature="sv")

    @dbus.service.signal(PROPS, signature="sa{sv}as")
    def PropertiesChanged(self, iface, changed, invalidated):
        pass


class Root(dbus.service.Object):
    def __init__(self, mock):
        self.mock = mock
        super().__init__(mock.bus, "/")

    @dbus.service.method(OM, out_signature="a{oa{sa{sv}}}")
    def GetManagedObjects(self):
        return {o.path: {o.iface: dbus.Dictionary(o.props, signature="sv")} for o in self.mock.objects()}

    @dbus.service.signal(OM, signature="oa{sa{sv}}")
    def InterfacesAdded(self, path, interfaces):
        pass

    @dbus.service.signal(OM, signature="oas")
    def InterfacesRemoved(self, path, interfaces):
        pass


class Adapter(PropertyObject):
    def __init__(self, mock, path):
        super().__init__(mock, path, ADAPTER, {"Address": "00:11:22:33:44:55", "Powered": True, "Discovering": False})

    @dbus.service.method(ADAPTER, in_signature="a{sv}")
    def SetDiscoveryFilter(self, f):
        self.mock.calls.append("SetDiscoveryFilter")

    @dbus.service.method(ADAPTER)
    def StartDiscovery(self):
        self.mock.calls.append("StartDiscovery")
        self.set(Discovering=True)
        if self.mock.device is None:
            GLib.timeout_add(200, self.mock.appear)

    @dbus.service.method(ADAPTER)
    def StopDiscovery(self):
        self.mock.calls.append("StopDiscovery")
        self.set(Discovering=False)


class Device(PropertyObject):
    def __init__(self, mock, path, address):
        super().__init__(mock, path, DEVICE, {
            "Address": address, "Name": "Hamster", "Alias": "Hamster", "Adapter": dbus.ObjectPath(mock.adapter.path),
            "Connected": False, "ServicesResolved": False, "Paired": False,
            "UUIDs": dbus.Array([SENSOR_SERVICE, EFFECTOR_SERVICE], signature="s")})

    @dbus.service.method(DEVICE, async_callbacks=("ok", "err"))
    def Connect(self, ok, err):
        self.mock.calls.append("Connect")
        if self.props["Connected"]:
            ok()
            return

        def done():
            if self.mock.device is not self:
                err(BluezError("Failed", "device removed"))
                return False
            self.mock.connections += 1
            self.set(Connected=True)
            ok()
            GLib.timeout_add(50, self.mock.resolve)
            return False
        GLib.timeout_add(int(self.mock.connect_delay_s * 1000), done)

    @dbus.service.method(DEVICE)
    def Disconnect(self):
        self.mock.calls.append("Disconnect")
        self.mock.drop()


class Characteristic(PropertyObject):
    def __init__(self, mock, path, service, uuid, flags):
        super().__init__(mock, path, CHAR, {
            "UUID": uuid, "Service": dbus.ObjectPath(service), "Flags": dbus.Array(flags, signature="s"),
            "Notifying": False, "Value": dbus.Array([], signature="y")})

    @dbus.service.method(CHAR)
    def StartNotify(self):
        self.mock.calls.append("StartNotify")
        if "notify" not in self.props["Flags"]:
            raise BluezError("NotSupported", "Operation is not supported")
        self.set(Notifying=True)

    @dbus.service.method(CHAR)
    def StopNotify(self):
        self.mock.calls.append("StopNotify")
        self.set(Notifying=False)

    @dbus.service.method(CHAR, in_signature="aya{sv}", async_callbacks=("ok", "err"))
    def WriteValue(self, value, options, ok, err):
        self.mock.calls.append("WriteValue")
        if not self.mock.device or not self.mock.device.props["Connected"]:
            return err(BluezError("NotConnected", "Not connected"))
        if "write-without-response" not in self.props["Flags"]:
            return err(BluezError("NotPermitted", "Write not permitted"))
        self.mock.writes.append((self.mock.connections, bytes(value), str(options.get("type", ""))))
        if self.mock.hold_writes:
            self.mock.held_acks.append(ok)  # acknowledged by HoldWrites(false)
        else:
            ok()

    def notify(self, payload):
        self.props["Value"] = dbus.Array(payload, signature="y")
        self.PropertiesChanged(CHAR, dbus.Dictionary({"Value": self.props["Value"]}, signature="sv"),
                               dbus.Array([], signature="s"))


class Service(PropertyObject):
    def __init__(self, mock, path, uuid):
        super().__init__(mock, path, SERVICE, {
            "UUID": uuid, "Primary": True, "Device": dbus.ObjectPath(mock.device.path)})


class Control(dbus.service.Object):
    def __init__(self, mock):
        self.mock = mock
        super().__init__(mock.bus, "/org/ddace/mock")

    @dbus.service.method(CONTROL, in_signature="ay")
    def SetSensor(self, payload):
        self.mock.sensor = bytes(payload)

    @dbus.service.method(CONTROL, in_signature="ay")
    def Notify(self, payload):
        if self.mock.sensor_char and self.mock.sensor_char.props["Notifying"]:
            self.mock.sensor_char.notify(bytes(payload))

    @dbus.service.method(CONTROL)
    def Drop(self):
        self.mock.drop()

    @dbus.service.method(CONTROL, in_signature="b")
    def Stall(self, stalled):
        self.mock.stalled = bool(stalled)

    @dbus.service.method(CONTROL, in_signature="b")
    def HoldWrites(self, hold):
        """While held, WriteValue calls are recorded but not answered (a congested link)."""
        self.mock.hold_writes = bool(hold)
        if not hold:
            acks, self.mock.held_acks = self.mock.held_acks, []
            for ok in acks:
                ok()

    @dbus.service.method(CONTROL)
    def Vanish(self):
        """BlueZ forgets the device (no Connected=false first)."""
        gatt, self.mock.gatt, self.mock.sensor_char = self.mock.gatt, [], None
        self.mock.remove(reversed(gatt))
        if self.mock.device:
            self.mock.remove([self.mock.device])
            self.mock.device = None

    @dbus.service.method(CONTROL, out_signature="a(uays)")
    def Writes(self):
        return dbus.Array([(dbus.UInt32(c), dbus.ByteArray(b), t) for c, b, t in self.mock.writes], signature="(uays)")

    @dbus.service.method(CONTROL, out_signature="as")
    def Calls(self):
        return dbus.Array(self.mock.calls, signature="s")


class Mock:
    def __init__(self, bus, adapter, address, connect_delay_s):
        self.bus, self.address, self.connect_delay_s = bus, address, connect_delay_s
        self.calls, self.writes, self.connections = [], [], 0
        # A valid, all-zero Hamster sensor payload (byte 2 = 0x10 marks a sensor packet).
        self.sensor, self.stalled = bytes([0, 0, 0x10] + [0] * 17), False
        self.hold_writes, self.held_acks = False, []
        self.root = Root(self)
        self.adapter = Adapter(self, "/org/bluez/" + adapter)
        self.device = None
        self.gatt = []
        self.sensor_char = None
        self.control = Control(self)
        GLib.timeout_add(20, self.tick)

    def objects(self):
        return [self.adapter] + ([self.device] if self.device else []) + self.gatt

    def add(self, objs):
        for o in objs:
            self.root.InterfacesAdded(o.path, {o.iface: dbus.Dictionary(o.props, signature="sv")})

    def remove(self, objs):
        for o in objs:
            o.remove_from_connection()
            self.root.InterfacesRemoved(o.path, dbus.Array([o.iface], signature="s"))

    def appear(self):
        if self.device is None:
            self.device = Device(self, self.adapter.path + "/dev_" + self.address.replace(":", "_"), self.address)
            self.add([self.device])
        return False

    def resolve(self):
        d = self.device
        if not d or not d.props["Connected"] or self.gatt:
            return False
        s1 = Service(self, d.path + "/service0001", SENSOR_SERVICE)
        c1 = Characteristic(self, s1.path + "/char0002", s1.path, SENSOR_CHAR, ["read", "notify"])
        s2 = Service(self, d.path + "/service000c", EFFECTOR_SERVICE)
        c2 = Characteristic(self, s2.path + "/char000d", s2.path, EFFECTOR_CHAR, ["write-without-response", "write"])
        self.gatt, self.sensor_char = [s1, c1, s2, c2], c1
        self.add(self.gatt)
        d.set(ServicesResolved=True)
        return False

    def drop(self):
        d = self.device
        if d and d.props["Connected"]:
            d.set(ServicesResolved=False)
            d.set(Connected=False)
        gatt, self.gatt, self.sensor_char = self.gatt, [], None
        self.remove(reversed(gatt))

    def tick(self):
        c = self.sensor_char
        if c and c.props["Notifying"] and not self.stalled:
            c.notify(self.sensor)
        return True


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--address", required=True)
    parser.add_argument("--adapter", default="hci0")
    parser.add_argument("--connect-delay", type=float, default=0.3)
    args = parser.parse_args()
    dbus.mainloop.glib.DBusGMainLoop(set_as_default=True)
    address = os.environ.get("DBUS_SYSTEM_BUS_ADDRESS")
    if not address:
        sys.exit("mock_bluez: DBUS_SYSTEM_BUS_ADDRESS is not set")
    bus = dbus.bus.BusConnection(address)
    loop = GLib.MainLoop()
    bus.call_on_disconnection(lambda _: loop.quit())
    Mock(bus, args.adapter, args.address.upper(), args.connect_delay)
    name = dbus.service.BusName(BLUEZ, bus, do_not_queue=True)  # noqa: F841 (kept while the loop runs)
    print("ready", flush=True)
    loop.run()


if __name__ == "__main__":
    main()
