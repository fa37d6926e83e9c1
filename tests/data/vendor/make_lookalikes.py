"""Writes the look-alike files of this corpus (see SOURCES.md).

A look-alike copies the *shape* of a real-world device description file whose
licence does not allow redistribution (or is unknown): its generator's layout,
key order, notations and slips. Names, values and vendors are our own, and the
object set is cut down to what shows those quirks. Run it from anywhere:
``python tests/data/vendor/make_lookalikes.py``; it rewrites the files in
place, so a changed file shows up in `git diff`.
"""

from __future__ import annotations

import os
from typing import Iterable, List, Optional, Tuple

HERE = os.path.dirname(os.path.abspath(__file__))

BAUD = (10, 20, 50, 125, 250, 500, 800, 1000)


def lines(*parts: str) -> str:
    return "\n".join(parts) + "\n"


def entry(section: str, name: str, dtype: str, access: str, default: Optional[str] = None,
          pdo: str = "0", object_type: str = "0x7", extra: Iterable[str] = (),
          comment: Optional[str] = None, default_first: bool = False) -> str:
    out = [f"[{section}]", f"ParameterName={name}", f"ObjectType={object_type}"]
    if comment:
        out.append(comment)
    if default_first and default is not None:
        out.append(f"DefaultValue={default}")
    out += [f"DataType={dtype}", f"AccessType={access}"]
    if default is not None and not default_first:
        out.append(f"DefaultValue={default}")
    out.append(f"PDOMapping={pdo}")
    out += list(extra)
    return lines(*out) + "\n"


def record(index: str, name: str, subs: List[Tuple[int, str, str, str, Optional[str]]],
           object_type: str = "0x9", sub_fmt: str = "{:X}", number: Optional[str] = None,
           comment: Optional[str] = None, sub_object_type: str = "0x7",
           extra: Iterable[str] = ()) -> str:
    head = [f"[{index}]", f"ParameterName={name}", f"ObjectType={object_type}"]
    if comment:
        head.append(comment)
    head.append(f"SubNumber={number if number is not None else len(subs)}")
    out = lines(*head) + "\n"
    for sub, sub_name, dtype, access, default in subs:
        out += entry(f"{index}sub{sub_fmt.format(sub)}", sub_name, dtype, access, default,
                     object_type=sub_object_type, comment=comment, extra=extra)
    return out


def object_list(name: str, indices: Iterable[str], count: Optional[int] = None,
                count_last: bool = False) -> str:
    keys = [f"{n}=0x{index}" for n, index in enumerate(indices, start=1)]
    total = f"SupportedObjects={len(keys) if count is None else count}"
    return lines(f"[{name}]", *(keys + [total] if count_last else [total] + keys)) + "\n"


def device_info(vendor: str, number: str, product: str, rx: int = 4, tx: int = 4,
                extra: Iterable[str] = ()) -> str:
    return lines("[DeviceInfo]", f"VendorName={vendor}", f"VendorNumber={number}",
                 f"ProductName={product}",
                 *(f"BaudRate_{rate}={1 if rate >= 125 else 0}" for rate in BAUD),
                 "SimpleBootUpMaster=0", "SimpleBootUpSlave=1", "Granularity=8",
                 "DynamicChannelsSupported=0", "CompactPDO=0", "GroupMessaging=0",
                 f"NrOfRXPDO={rx}", f"NrOfTXPDO={tx}", "LSS_Supported=0", *extra) + "\n"


DUMMY = lines("[DummyUsage]", *(f"Dummy000{n}=0" for n in range(1, 8))) + "\n"
IDENTITY = [(0, "Number of entries", "0x0005", "ro", "4"), (1, "Vendor ID", "0x0007", "ro", None),
            (2, "Product code", "0x0007", "ro", None), (3, "Revision number", "0x0007", "ro", None),
            (4, "Serial number", "0x0007", "ro", None)]


def write(name: str, text: str) -> None:
    with open(os.path.join(HERE, name), "w", encoding="utf-8", newline="\n") as handle:
        handle.write(text)


# ---------------------------------------------------------------- EDS look-alikes
def e35_like() -> str:
    """python-canopen's test/e35.eds as the issue reports it: SupportedObjects
    counts one object more than the list names."""
    optional = ["1005", "1008", "1014", "1017"]
    return (lines("[FileInfo]", "FileName=e35_like.eds", "EDSVersion=4.0",
                  "CreatedBy=canopenfd corpus") + "\n"
            + device_info("Example Sensors", "0x0000ABCD", "E-series look-alike")
            + object_list("MandatoryObjects", ["1000", "1001", "1018"])
            + entry("1000", "Device type", "0x0007", "ro", "0x00020194")
            + entry("1001", "Error register", "0x0005", "ro", "0")
            + record("1018", "Identity object", IDENTITY)
            + object_list("OptionalObjects", optional, count=len(optional) + 1)
            + entry("1005", "COB-ID SYNC", "0x0007", "rw", "0x80")
            + entry("1008", "Manufacturer device name", "0x0009", "const", "E35 look-alike")
            + entry("1014", "COB-ID EMCY", "0x0007", "rw", "$NODEID+0x80")
            + entry("1017", "Producer heartbeat time", "0x0006", "rw", "250"))


def drive_a_like() -> str:
    """Technosoft iPOS file in ros_canopen: lines holding one blank after
    objects, EDSVersion=4, AccessType rwr, $NODEID+0x80000380 offsets."""
    text = lines("[FileInfo]", "CreatedBy=A. Author", "Description=CANopen drive A",
                 "FileName=driveA.v1.eds", "FileVersion=0x01", "FileRevision=0x04",
                 "EDSVersion=4") + "\n"
    text += device_info("Drive Maker A", "0x00000F0A", "Drive A", extra=["LSS_Supported=1"])
    text += DUMMY + lines("[Comments]", "Lines=0") + "\n"
    text += object_list("MandatoryObjects", ["1000", "1001", "1018"])
    text += entry("1000", "Device type", "0x0007", "ro", "0x60192").rstrip("\n") + "\n \n\n"
    text += entry("1001", "Error register", "0x0005", "ro").rstrip("\n") + "\n \n\n"
    text += record("1018", "Identity Object", [(0, "number of entries", "0x0005", "ro", "4"),
                                               (1, "Vendor ID", "0x0007", "ro", "0x00000F0A")]
                   + IDENTITY[2:], number="5")
    text += object_list("OptionalObjects", ["1013", "1014", "1017", "1802", "6040", "6041"])
    text += entry("1013", "High Resolution Time Stamp", "0x0007", "rwr", "0x00000000", "1")
    text += entry("1014", "COB-ID EMCY Message", "0x0007", "rw", "$NODEID+0x80")
    text += entry("1017", "Producer Heartbeat Time", "0x0006", "rw", "0")
    text += record("1802", "TPDO3 Communication Parameter",
                   [(0, "Number of entries", "0x0005", "ro", "5"),
                    (1, "COB-ID TPDO3", "0x0007", "rw", "$NODEID+0x80000380"),
                    (2, "Transmision type", "0x0005", "rw", "0x01"),
                    (3, "Inhibit Time", "0x0006", "rw", "0x012C"),
                    (5, "Event timer", "0x0006", "rw", "0")], number="5")
    text += entry("6040", "Control word", "0x0006", "rww", "0", "1")
    text += entry("6041", "Status word", "0x0006", "ro", "0", "1")
    return text


def drive_b_like() -> str:
    """Technosoft ISD860 file in ros_canopen: ';StorageLocation=RAM' comment
    lines inside sections, empty DefaultValue=, '$NODEID +0x80' and
    '$NODEID + 0x600' spacing, AccessType rww/wo, SubNumber=0x2 with two subs,
    a ';LSS_Type=' commented key and an absolute LastEDS path."""
    comment = ";StorageLocation=RAM"
    text = lines("[FileInfo]", "FileName=driveB.eds", "FileVersion=1", "FileRevision=0",
                 "LastEDS=/home/someone/ws/src/driveB/config/driveB.eds", "EDSVersion=4.0",
                 "CreationTime=12:00AM", "CreationDate=01-01-0001") + "\n"
    text += device_info("Drive Maker B", "419", "Drive B", extra=[";LSS_Type=Server"])
    text += DUMMY + lines("[Comments]", "Lines=0") + "\n"
    text += object_list("MandatoryObjects", ["1000", "1001", "1018"])
    text += entry("1000", "Device type", "0x0007", "ro", "0x60192", comment=comment)
    text += entry("1001", "Error register", "0x0005", "ro", "", comment=comment)
    text += record("1018", "Identity Object", [(0, "number of entries", "0x0005", "ro", "1"),
                                               (1, "Vendor ID", "0x0007", "ro", "0x000001A3")],
                   number="0x2", comment=comment)
    text += object_list("OptionalObjects", ["1014", "1200", "6040", "6060", "6064"])
    text += entry("1014", "COB-ID EMCY Message", "0x0007", "ro", "$NODEID +0x80", comment=comment)
    text += record("1200", "Server SDO Parameter",
                   [(0, "Number of entries", "0x0005", "ro", "2"),
                    (1, "COB-ID Client -> Server (rx)", "0x0007", "ro", "$NODEID + 0x600"),
                    (2, "COB-ID Server -> Client (tx)", "0x0007", "ro", "$NODEID + 0x580")],
                   number="0x3", comment=comment)
    text += entry("6040", "Control word", "0x0006", "rww", "", "1", comment=comment,
                  extra=["HighLimit=65535", "LowLimit=0"])
    text += entry("6060", "Modes of Operation", "0x0002", "wo", "", "1", comment=comment,
                  extra=["HighLimit=127", "LowLimit=-128"])
    text += entry("6064", "Position actual value", "0x0004", "ro", "", "1", comment=comment)
    return text


def gripper_like() -> str:
    """SCHUNK PRL120 file in ros_canopen: ObjFlags=0x0 on every object,
    ParameterValue without DefaultValue, hex limits, TPDO records with
    SubNumber=4 naming sub-indices 0, 1, 2 and 5."""
    flags = ["ObjFlags=0x0"]
    text = lines("[FileInfo]", "CreatedBy=Gripper Maker", "Description=EDS File for a "
                 "rotary unit", "FileName=rotary.eds", "FileVersion=0x01",
                 "FileRevision=0x01", "EDSVersion=4.0") + "\n"
    text += device_info("Gripper Maker GmbH", "0x00000000", "ROT90", rx=2, tx=4)
    text += lines("[DummyUsage]", "Dummy0001=0", *(f"Dummy000{n}=1" for n in range(2, 8))) + "\n"
    text += lines("[Comments]", "Lines=0") + "\n"
    text += object_list("MandatoryObjects", ["1000", "1001", "1018"])
    text += entry("1000", "Device type", "0x0007", "ro", "0x00020192", extra=flags)
    text += entry("1001", "Error register", "0x0005", "ro", extra=flags)
    text += record("1018", "Identity Object", IDENTITY, extra=["ObjFlags=0"])
    text += object_list("OptionalObjects", ["1017", "1600", "1801", "6041", "607A"])
    text += entry("1017", "Producer heartbeat time", "0x0006", "rw", "0x00000000",
                  extra=["LowLimit=0", "HighLimit=32767"] + flags)
    text += lines("[1600]", "ParameterName=1. Receive PDO Mapping", "ObjectType=0x9",
                  "SubNumber=3", *flags) + "\n"
    text += lines("[1600sub0]", "ParameterName=Number of mapped Application Objects",
                  "ObjectType=0x7", "DataType=0x0005", "AccessType=rw", "ParameterValue=2",
                  "PDOMapping=0", "LowLimit=0", "HighLimit=8", "ObjFlags=0") + "\n"
    for sub, value in ((1, "0x60400010"), (2, "0x607a0020")):
        text += lines(f"[1600sub{sub}]", f"ParameterName={sub}. mapped Object",
                      "ObjectType=0x7", "DataType=0x0007", "AccessType=rw",
                      f"ParameterValue={value}", "PDOMapping=0", "ObjFlags=0") + "\n"
    text += record("1801", "2. Transmit PDO Parameter",
                   [(0, "Largest Sub-Index supported", "0x0005", "ro", "5"),
                    (1, "COB-ID used by PDO", "0x0007", "rw", "$NODEID+0x80000280"),
                    (2, "Transmission Type", "0x0005", "rw", "1"),
                    (5, "event timer", "0x0006", "rw", "0")], number="4",
                   extra=["LowLimit=0x00", "ObjFlags=0"])
    text += entry("6041", "Status word", "0x0006", "ro", pdo="1", extra=flags)
    text += entry("607A", "Target position", "0x0004", "rw", "0", "1", extra=flags)
    return text


def scanned_like() -> str:
    """Schunk.eds in ros_canopen, written by a scanning tool: no vendor keys
    in [DeviceInfo], compact arrays with a DefaultValue, a ParameterValue
    with $NODEID next to a different DefaultValue, hex limits on COB-IDs."""
    text = lines("[FileInfo]", "CreatedBy=Some EDS Scanner", "ModifiedBy=-",
                 "Description=Scanned from a device", "FileName=scanned.eds",
                 "EDSVersion=4.0") + "\n"
    text += lines("[DeviceInfo]", *(f"BaudRate_{rate}={1 if rate >= 50 else 0}" for rate in BAUD),
                  "SimpleBootUpSlave=1", "Granularity=8", "NrOfRXPDO=2", "NrOfTXPDO=1",
                  "LSS_Supported=1") + "\n"
    text += object_list("MandatoryObjects", ["1000", "1001", "1018"])
    text += entry("1000", "Device type", "0x0007", "ro")
    text += entry("1001", "Error register", "0x0005", "ro")
    text += record("1018", "Identity object", [(0, "Highest sub-index supported", "0x0005",
                                                "const", "0x4")] + IDENTITY[1:])
    text += object_list("OptionalObjects", ["1003", "1014", "1016", "1401", "1A01", "6046"])
    text += lines("[1003]", "ParameterName=Pre-defined error field", "ObjectType=0x8",
                  "DataType=0x0007", "AccessType=ro", "PDOMapping=0", "CompactSubObj=254") + "\n"
    text += entry("1014", "COB-ID EMCY message", "0x0007", "rw", "$NODEID+0x00000080",
                  extra=["LowLimit=0x00000080", "HighLimit=0xBFFFFFFF"])
    text += lines("[1016]", "ParameterName=Consumer heartbeat time", "ObjectType=0x8",
                  "DataType=0x0007", "AccessType=rw", "DefaultValue=0x0", "PDOMapping=0",
                  "CompactSubObj=3") + "\n"
    text += lines("[1401]", "ParameterName=RPDO communication parameter 1", "ObjectType=0x9",
                  "SubNumber=2") + "\n"
    text += entry("1401sub0", "Highest sub-index supported", "0x0005", "const", "0x2",
                  extra=["LowLimit=0x02", "HighLimit=0x05"])
    text += entry("1401sub1", "COB-ID used by RPDO", "0x0007", "rw", "$NODEID+0x80000300",
                  extra=["LowLimit=0x00000080", "HighLimit=0xFFFFFFFF",
                         "ParameterValue=$NODEID+0x300"])
    text += record("1A01", "TPDO mapping parameter 1",
                   [(0, "Number of mapped application objects in TPDO", "0x0005", "rw",
                     "0x0")], number="1")
    text += record("6046", "vl_velocity_min_max_amount",
                   [(0, "vl_velocity_min_max_amount_highest_subindex", "0x0005", "const", "0x2"),
                    (1, "vl_velocity_min_max_amount_min", "0x0007", "rw", None),
                    (2, "vl_velocity_min_max_amount_max", "0x0007", "rw", None)],
                   object_type="0x8")
    return text


def gocanopen_like() -> str:
    """gocanopen's testdata/test_zipped_format.eds: SupportedObjects=3 above
    six keys, one object listed three times, VendorName="" in quotes, hex
    sub-indices up to [1003sub10], '0x80+$NODEID' and '0x80000200+$NODEID'."""
    comment = ";StorageLocation=RAM"
    text = lines("[FileInfo]", "FileName=zipped", "FileVersion=1", "LastEDS=",
                 "EDSVersion=4.0", "Description=", "CreationTime=1:00PM",
                 "CreationDate=06-30-2024", "CreatedBy=") + "\n"
    text += device_info('""', "0", "Zipped Product")
    text += object_list("MandatoryObjects", ["1000", "1001", "1008", "1009", "100A", "1018"],
                        count=3)
    text += entry("1000", "Device type", "0x0007", "ro", "0x00000000", comment=comment)
    text += entry("1001", "Error register", "0x0005", "ro", "0x00", "1", comment=comment)
    text += entry("1008", "Manufacturer device name", "0x0009", "const", "ZIP", comment=comment)
    text += entry("1009", "Manufacturer hardware version", "0x0009", "const", "hw2",
                  comment=comment)
    text += entry("100A", "Manufacturer software version", "0x0009", "const", "v0.9.1z",
                  comment=comment) + "\n"
    text += record("1018", "Identity", [(0, "Highest sub-index supported", "0x0005", "ro",
                                         "0x04")] + IDENTITY[1:], number="0x5", comment=comment)
    text += object_list("OptionalObjects", ["1003", "1014", "1019", "1019", "1019", "1400"])
    subs = [(0, "Number of errors", "0x0005", "rw", "")] + [
        (n, "Standard error field", "0x0007", "ro", "") for n in range(1, 17)]
    text += record("1003", "Pre-defined error field", subs, object_type="0x8",
                   number="0x11", comment=comment)
    text += entry("1014", "COB-ID EMCY", "0x0007", "rw", "0x80+$NODEID", comment=comment)
    text += entry("1019", "Synchronous counter overflow value", "0x0005", "rw", "0",
                  comment=comment)
    text += record("1400", "RPDO communication parameter",
                   [(0, "Highest sub-index supported", "0x0005", "ro", "0x05"),
                    (1, "COB-ID used by RPDO", "0x0007", "rw", "0x80000200+$NODEID"),
                    (2, "Transmission type", "0x0005", "rw", "254"),
                    (5, "Event timer", "0x0006", "rw", "0")], number="0x4", comment=comment)
    return text


def spaced_like() -> str:
    """heig-vd canopen-stack's golden minimal od.eds: 'key = value' spacing,
    ISO dates, 'Baudrate_' spelling, sub-objects carrying the record's
    ObjectType = 0x09, a DOMAIN with DefaultValue = 0, an empty string default."""
    def kv(section: str, pairs: List[Tuple[str, str]]) -> str:
        return lines(f"[{section}]", *(f"{k} = {v}" if v else f"{k} = " for k, v in pairs)) + "\n"

    def var(section: str, name: str, object_type: str, dtype: str, access: str, default: str,
            pdo: str = "0") -> str:
        return kv(section, [("ParameterName", name), ("ObjectType", object_type),
                            ("DataType", dtype), ("AccessType", access), ("PDOMapping", pdo),
                            ("DefaultValue", default)])

    text = kv("FileInfo", [("FileName", "tiny.eds"), ("FileVersion", "1"), ("EDSVersion", "4.0"),
                           ("CreationDate", "2025-01-31"), ("CreatedBy", "a generator")])
    text += kv("DeviceInfo", [("VendorName", "Tiny Labs"), ("VendorNumber", "0"),
                              ("ProductName", "tiny"), ("ProductNumber", "7")]
               + [(f"Baudrate_{rate}", "1") for rate in BAUD])
    text += kv("MandatoryObjects", [("SupportedObjects", "4"), ("1", "0x1000"), ("2", "0x1001"),
                                    ("3", "0x1017"), ("4", "0x1018")])
    text += var("1000", "Device type", "0x07", "0x07", "ro", "0x00000192")
    text += var("1001", "Error register", "0x07", "0x05", "ro", "0", "1")
    text += var("1017", "Producer hearbeat time", "0x07", "0x06", "rw", "750")
    text += kv("1018", [("ParameterName", "Identity object"), ("ObjectType", "0x09"),
                        ("SubNumber", "3")])
    text += var("1018sub0", "Number of entries", "0x09", "0x05", "ro", "2")
    text += var("1018sub1", "Vendor-ID", "0x09", "0x07", "ro", "0")
    text += var("1018sub2", "Product code", "0x09", "0x07", "ro", "7")
    text += kv("OptionalObjects", [("SupportedObjects", "3"), ("1", "0x2001"), ("2", "0x2002"),
                                   ("3", "0x2003")])
    text += var("2001", "A string", "0x07", "0x09", "ro", "")
    text += var("2002", "A domain", "0x02", "0x0F", "rw", "0")
    text += var("2003", "A limited value", "0x07", "0x06", "rw", "42")
    return text


def satellite_like() -> str:
    """OreSat's battery.dcf in CANopen-monitor: [DeviceCommissioning] (double
    m) with NodeId=4 and BaudRate=0, every entry with an empty Denotation= and
    ParameterValue=, '0x80+$NODEID', RPDO records naming sub-indices 0,1,2,5."""
    def var(section: str, name: str, dtype: str, access: str, default: str,
            pdo: str = "0") -> str:
        return lines(f"[{section}]", f"ParameterName={name}", "Denotation=", "ObjectType=0x7",
                     ";StorageLocation=RAM", f"DataType={dtype}", f"AccessType={access}",
                     f"DefaultValue={default}", "ParameterValue=", f"PDOMapping={pdo}") + "\n"

    text = lines("[FileInfo]", "FileName=power.dcf", "FileVersion=0", "FileRevision=1",
                 "LastEDS=", "EDSVersion=4.0", "Description=Power board object dictionary",
                 "CreationTime=3:51PM", "CreationDate=08-12-2019", "ModifiedBy=") + "\n"
    text += device_info("Student Space Club", "0", "Power board", rx=16, tx=16)
    text += DUMMY + lines("[Comments]", "Lines=0") + "\n"
    text += lines("[DeviceCommissioning]", "NodeId=4", "NodeName=Power", "BaudRate=0",
                  "NetNumber=0", "NetworkName=", "CANopenManager=0", "LSS_SerialNumber=0") + "\n"
    text += object_list("MandatoryObjects", ["1000", "1001", "1018"])
    text += var("1000", "Device type", "0x0007", "ro", "0x00000000")
    text += var("1001", "Error register", "0x0005", "ro", "0x00", "1")
    text += lines("[1018]", "ParameterName=Identity", "Denotation=", "ObjectType=0x9",
                  ";StorageLocation=ROM", "SubNumber=0x2") + "\n"
    text += var("1018sub0", "Highest sub-index supported", "0x0005", "ro", "0x01")
    text += var("1018sub1", "Vendor-ID", "0x0007", "ro", "0x00000000")
    text += object_list("OptionalObjects", ["1008", "1014", "1017", "1400", "6000"])
    text += var("1008", "Manufacturer device name", "0x0009", "ro", "Power Node")
    text += var("1014", "COB-ID EMCY", "0x0007", "rw", "0x80+$NODEID")
    text += var("1017", "Producer heartbeat time", "0x0006", "rw", "1000")
    text += lines("[1400]", "ParameterName=RPDO communication parameter", "Denotation=",
                  "ObjectType=0x9", "SubNumber=0x4") + "\n"
    text += var("1400sub0", "Highest sub-index supported", "0x0005", "ro", "0x05")
    text += var("1400sub1", "COB-ID used by RPDO", "0x0007", "rw", "0x80000200+$NODEID")
    text += var("1400sub2", "Transmission type", "0x0005", "rw", "254")
    text += var("1400sub5", "Event timer", "0x0006", "rw", "0")
    text += var("6000", "Cell voltage", "0x0006", "ro", "3700", "1")
    return text


def editor_v4_like(name: str, dup_default: bool) -> str:
    """CANopenEditor v4 EDS as in CANopenSocket's basicDevice.eds and
    canopen-rust's demoDevice.eds: empty VendorNumber=/ProductNumber=,
    ;StorageLocation comments, '0x80+$NODEID', '$NODEID+0x00000200' and, in
    the second, [1018sub0] carrying DefaultValue twice (the empty one last)."""
    comment = ";StorageLocation=PERSIST_COMM"
    text = lines("[FileInfo]", f"FileName={name}", "FileVersion=1", "FileRevision=1",
                 "LastEDS=", "EDSVersion=4.0", "Description=Editor v4 style device",
                 "CreationTime=12:37PM", "CreationDate=11-28-2020",
                 "ModificationTime=7:31PM", "ModificationDate=03-16-2021") + "\n"
    text += device_info("", "" if not dup_default else "0", "Editor device")
    text += lines("[DummyUsage]", "Dummy0001=0", *(f"Dummy000{n}=1" for n in range(2, 8))) + "\n"
    text += lines("[Comments]", "Lines=0") + "\n"
    text += object_list("MandatoryObjects", ["1000", "1001", "1018"])
    text += entry("1000", "Device type", "0x0007", "ro", "0x000F0191", comment=comment)
    text += entry("1001", "Error register", "0x0005", "ro", "0x00", "1", comment=comment)
    text += lines("[1018]", "ParameterName=Identity", "ObjectType=0x9", comment, "SubNumber=0x3"
                  ) + "\n"
    sub0 = entry("1018sub0", "Highest sub-index supported", "0x0005", "ro", "0x02",
                 comment=";StorageLocation=RAM")
    if dup_default:
        sub0 = sub0.rstrip("\n") + "\nDefaultValue=\n\n"
    text += sub0
    text += entry("1018sub1", "Vendor-ID", "0x0007", "ro", "0x00000000", comment=comment)
    text += entry("1018sub2", "Product code", "0x0007", "ro", "0x00000002", comment=comment)
    text += object_list("OptionalObjects", ["1014", "1017", "1200", "1400"])
    text += entry("1014", "COB-ID EMCY", "0x0007", "rw",
                  "$NODEID+0x80" if dup_default else "0x80+$NODEID", comment=comment)
    text += entry("1017", "Producer heartbeat time", "0x0006", "rw", "0", comment=comment)
    text += record("1200", "SDO server parameter",
                   [(0, "Highest sub-index supported", "0x0005", "ro", "2"),
                    (1, "COB-ID client to server (rx)", "0x0007", "ro",
                     "$NODEID+0x600" if dup_default else "0x600+$NODEID"),
                    (2, "COB-ID server to client (tx)", "0x0007", "ro",
                     "$NODEID+0x580" if dup_default else "0x580+$NODEID")],
                   number="0x3", comment=";StorageLocation=RAM")
    text += record("1400", "RPDO communication parameter",
                   [(0, "Highest sub-index supported", "0x0005", "ro", "0x05"),
                    (1, "COB-ID used by RPDO", "0x0007", "rw",
                     "$NODEID+0x00000200" if dup_default else "0x00000200+$NODEID"),
                    (2, "Transmission type", "0x0005", "rw", "255"),
                    (5, "Event timer", "0x0006", "rw", "0")], number="0x4", comment=comment)
    return text


def ros_slave_like() -> str:
    """cia402_slave.eds in ros_canopen: no [FileInfo], [Comments] before
    [DummyUsage], [ManufacturerObjects] before [OptionalObjects], DataType=5
    without 0x, AccessType=const on 0x1000, ObjFlags on store entries and
    '$NODEID+0x80000200' COB-IDs."""
    text = lines("[DeviceInfo]", "VendorName=Robot Lab", "VendorNumber=0x777",
                 "ProductName=VIRTUAL402", "ProductNumber=0x002", "OrderCode=VIRTUAL402",
                 *(f"BaudRate_{rate}=1" for rate in BAUD), "Granularity=8",
                 "SimpleBootUpSlave=1", "NrOfRXPDO=1", "NrOfTXPDO=1") + "\n"
    text += lines("[Comments]", "Lines=0") + "\n" + DUMMY
    text += object_list("MandatoryObjects", ["1000", "1001", "1018"])
    text += object_list("ManufacturerObjects", [])
    text += object_list("OptionalObjects", ["1010", "1400", "6040", "6041"])
    text += entry("1000", "Device Type", "0x0007", "const", "0xFFFF0192", object_type="0x07")
    text += entry("1001", "Error Register", "0x0005", "ro", object_type="0x07")
    text += lines("[1018]", "SubNumber=3", "ParameterName=Identity Object", "ObjectType=0x09"
                  ) + "\n"
    text += entry("1018sub0", "number of entries", "5", "ro", "0x2", object_type="0x07")
    text += entry("1018sub1", "Vendor Id", "0x0007", "ro", "0x777", object_type="0x07")
    text += entry("1018sub2", "Product Code", "0x0007", "ro", "0x2", object_type="0x07")
    text += lines("[1010]", "SubNumber=2", "ParameterName=Store Parameter Field",
                  "ObjectType=0x08") + "\n"
    text += entry("1010sub0", "Number of Entries", "5", "ro", "0x1", object_type="0x07")
    text += entry("1010sub1", "Save all Parameters", "0x0007", "rw", object_type="0x07",
                  extra=["ObjFlags=0x00000001"])
    text += lines("[1400]", "SubNumber=3", "ParameterName=Receive PDO Communication "
                  "Parameter 1", "ObjectType=0x09") + "\n"
    text += entry("1400sub0", "Number of Entries", "0x0005", "ro", "0x02", object_type="0x07")
    text += entry("1400sub1", "COB-ID", "0x0007", "rw", "$NODEID+0x80000200", object_type="0x07")
    text += entry("1400sub2", "Transmission Type", "0x0005", "rw", "0xFF", object_type="0x07")
    text += entry("6040", "Controlword", "0x0006", "rww", "0", "1", object_type="0x07")
    text += entry("6041", "Statusword", "0x0006", "ro", "0", "1", object_type="0x07")
    return text


def legacy_node_like() -> str:
    """CANopenNode's old Object Dictionary Editor (S32K144 sensor EDS): ';'
    header lines and blank lines before [FileInfo], FileName without
    extension, 24-hour CreationTime with seconds and an ISO date, a
    lower-case 'line5=' key in [Comments], ObjectType=7 in decimal, key order
    PDOMapping before DefaultValue."""
    text = ("\n; CANopen Electronic Data Sheet\n; File was automatically generated by an "
            "editor\n; See the editor's web site\n\n\n")
    text += lines("[FileInfo]", "FileName=Sensor_board", "FileVersion=1.0", "FileRevision=0",
                  "EDSVersion=4.0", "CreationTime=12:24:51", "CreationDate=2018-03-01",
                  "CreatedBy=someone") + "\n\n"
    text += device_info("Sensor Works", "0", "Sensor board") + "\n"
    text += lines("[Comments]", "Lines=3", "Line1=EDS File for a sensor board",
                  "Line2=Generated by an object dictionary editor", "line3=see the web site"
                  ) + "\n\n"
    text += object_list("MandatoryObjects", ["1000", "1001", "1018"]) + "\n"

    def old(section: str, name: str, dtype: str, access: str, default: str,
            pdo: str = "0") -> str:
        return lines(f"[{section}]", f"ParameterName={name}", "ObjectType=7",
                     f"DataType={dtype}", f"AccessType={access}", f"PDOMapping={pdo}",
                     f"DefaultValue={default}") + "\n"

    text += old("1000", "Device type", "0x0007", "ro", "0x00000000")
    text += old("1001", "Error register", "0x0005", "ro", "0", "1")
    text += lines("[1018]", "ParameterName=Identity", "ObjectType=9", "SubNumber=2") + "\n"
    text += old("1018sub0", "max sub-index", "0x0005", "ro", "1")
    text += old("1018sub1", "Vendor-ID", "0x0007", "ro", "0x00000000")
    text += object_list("OptionalObjects", ["1014", "1017", "1800", "2110"])
    text += old("1014", "COB-ID EMCY", "0x0007", "ro", "$NODEID+0x80")
    text += old("1017", "Producer heartbeat time", "0x0006", "rw", "5000")
    text += lines("[1800]", "ParameterName=TPDO communication parameter", "ObjectType=9",
                  "SubNumber=3") + "\n"
    text += old("1800sub0", "max sub-index", "0x0005", "ro", "2")
    text += old("1800sub1", "COB-ID used by TPDO", "0x0007", "rw", "$NODEID+0x80000180")
    text += old("1800sub2", "transmission type", "0x0005", "rw", "254")
    text += old("2110", "Variable Int32", "0x0004", "rw", "-12", "1")
    return text


# ---------------------------------------------------------------- XDD look-alikes
def editor_xdd_like(file_name: str, with_bitstring: bool) -> str:
    """CANopenEditor XDDs (CANopenDemo's demoDevice.xdd, canopennode-rtt's
    project.xdd): a ProfileBody_Device_CANopen with q1:-prefixed
    dataTypeList and parameterList, and a ProfileBody_CommunicationNetwork
    whose CANopenObjectList carries only names and uniqueIDRefs; types,
    access and defaults ('0x600+$NODEID') live in the parameters, some of
    which have no access attribute. The second has an OS command record whose
    Command/Reply are <BITSTRING/>, which has no CANopen basic type."""
    def param(uid: str, label: str, iec: str, default: Optional[str],
              access: Optional[str] = "readWrite") -> str:
        acc = f' access="{access}"' if access else ""
        value = f'\n            <q1:defaultValue value="{default}" />' if default is not None else ""
        return (f'          <q1:parameter uniqueID="{uid}"{acc}>\n'
                f'            <label lang="en">{label}</label>\n'
                f"            <{iec} />{value}\n          </q1:parameter>\n")

    params = param("UID_OBJ_1000", "Device type", "UDINT", "0x00000000", None)
    params += param("UID_OBJ_1014", "COB-ID EMCY", "UDINT", "0x80+$NODEID")
    params += param("UID_OBJ_1017", "Producer heartbeat time", "UINT", "0")
    params += param("UID_SUB_101800", "Highest sub-index supported", "USINT", "0x02", None)
    params += param("UID_SUB_101801", "Vendor-ID", "UDINT", "0x00000000", None)
    params += param("UID_SUB_101802", "Product code", "UDINT", "0x00000005", None)
    params += param("UID_SUB_120000", "Highest sub-index supported", "USINT", "2", None)
    params += param("UID_SUB_120001", "COB-ID client to server (rx)", "UDINT", "0x600+$NODEID",
                    None)
    params += param("UID_SUB_120002", "COB-ID server to client (tx)", "UDINT", "0x580+$NODEID",
                    None)
    params += param("UID_OBJ_2110", "Variable Int32", "DINT", "-7")
    objects = (
        '          <CANopenObject index="1000" name="Device type" objectType="7" '
        'PDOmapping="no" uniqueIDRef="UID_OBJ_1000" />\n'
        '          <CANopenObject index="1014" name="COB-ID EMCY" objectType="7" '
        'PDOmapping="no" uniqueIDRef="UID_OBJ_1014" />\n'
        '          <CANopenObject index="1017" name="Producer heartbeat time" objectType="7" '
        'PDOmapping="no" uniqueIDRef="UID_OBJ_1017" />\n'
        '          <CANopenObject index="1018" name="Identity" objectType="9" subNumber="3">\n'
        '            <CANopenSubObject subIndex="00" name="Highest sub-index supported" '
        'objectType="7" PDOmapping="no" uniqueIDRef="UID_SUB_101800" />\n'
        '            <CANopenSubObject subIndex="01" name="Vendor-ID" objectType="7" '
        'PDOmapping="no" uniqueIDRef="UID_SUB_101801" />\n'
        '            <CANopenSubObject subIndex="02" name="Product code" objectType="7" '
        'PDOmapping="no" uniqueIDRef="UID_SUB_101802" />\n'
        "          </CANopenObject>\n"
        '          <CANopenObject index="1200" name="SDO server parameter" objectType="9" '
        'subNumber="3">\n'
        '            <CANopenSubObject subIndex="00" name="Highest sub-index supported" '
        'objectType="7" PDOmapping="no" uniqueIDRef="UID_SUB_120000" />\n'
        '            <CANopenSubObject subIndex="01" name="COB-ID client to server (rx)" '
        'objectType="7" PDOmapping="optional" uniqueIDRef="UID_SUB_120001" />\n'
        '            <CANopenSubObject subIndex="02" name="COB-ID server to client (tx)" '
        'objectType="7" PDOmapping="optional" uniqueIDRef="UID_SUB_120002" />\n'
        "          </CANopenObject>\n"
        '          <CANopenObject index="2110" name="Variable Int32" objectType="7" '
        'PDOmapping="optional" uniqueIDRef="UID_OBJ_2110" />\n')
    if with_bitstring:
        params += param("UID_SUB_102300", "Highest sub-index supported", "USINT", "0x03", None)
        params += param("UID_SUB_102301", "Command", "BITSTRING", None)
        params += param("UID_SUB_102302", "Status", "USINT", "0x00", "read")
        objects += (
            '          <CANopenObject index="1023" name="OS command" objectType="9" '
            'subNumber="3">\n'
            '            <CANopenSubObject subIndex="00" name="Highest sub-index supported" '
            'objectType="7" PDOmapping="no" uniqueIDRef="UID_SUB_102300" />\n'
            '            <CANopenSubObject subIndex="01" name="Command" objectType="7" '
            'PDOmapping="no" uniqueIDRef="UID_SUB_102301" />\n'
            '            <CANopenSubObject subIndex="02" name="Status" objectType="7" '
            'PDOmapping="no" uniqueIDRef="UID_SUB_102302" />\n'
            "          </CANopenObject>\n")
    vendor = "0x00000000" if with_bitstring else ""
    return (
        '<?xml version="1.0" encoding="utf-8"?>\n'
        "<!--Look-alike of a file generated by an XDD editor (canopenfd test corpus)-->\n"
        '<ISO15745ProfileContainer xmlns:xsd="http://www.w3.org/2001/XMLSchema" '
        'xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" '
        'xmlns="http://www.canopen.org/xml/1.1">\n'
        "  <ISO15745Profile>\n"
        '    <ProfileHeader xmlns="">\n'
        "      <ProfileIdentification>CANopen device profile</ProfileIdentification>\n"
        "      <ProfileRevision>1.1</ProfileRevision>\n"
        "      <ProfileName />\n"
        "    </ProfileHeader>\n"
        '    <ProfileBody xmlns:q1="http://www.canopen.org/xml/1.1" '
        'xsi:type="q1:ProfileBody_Device_CANopen" formatName="CANopen" formatVersion="1.0" '
        f'fileName="{file_name}" fileCreator="corpus" fileCreationDate="2024-05-01" '
        'fileVersion="1" xmlns="">\n'
        "      <q1:DeviceIdentity>\n"
        "        <q1:vendorName>Look-alike Devices</q1:vendorName>\n"
        f"        <q1:vendorID>{vendor}</q1:vendorID>\n"
        "        <q1:productName>Editor demo look-alike</q1:productName>\n"
        "      </q1:DeviceIdentity>\n"
        "      <q1:ApplicationProcess>\n"
        "        <q1:parameterList>\n" + params +
        "        </q1:parameterList>\n"
        "      </q1:ApplicationProcess>\n"
        "    </ProfileBody>\n"
        "  </ISO15745Profile>\n"
        "  <ISO15745Profile>\n"
        '    <ProfileHeader xmlns="">\n'
        "      <ProfileIdentification>CANopen communication network profile"
        "</ProfileIdentification>\n"
        "    </ProfileHeader>\n"
        '    <ProfileBody xmlns:q1="http://www.canopen.org/xml/1.1" '
        'xsi:type="q1:ProfileBody_CommunicationNetwork_CANopen" formatName="CANopen" '
        f'formatVersion="1.0" fileName="{file_name}" fileCreator="corpus" '
        'fileCreationDate="2024-05-01" fileVersion="1" xmlns="">\n'
        "      <ApplicationLayers>\n"
        "        <CANopenObjectList>\n" + objects +
        "        </CANopenObjectList>\n"
        "      </ApplicationLayers>\n"
        "    </ProfileBody>\n"
        "  </ISO15745Profile>\n"
        "</ISO15745ProfileContainer>\n")


FILES = {
    "pycanopen_e35_like.eds": e35_like,
    "drive_a_like.eds": drive_a_like,
    "drive_b_like.eds": drive_b_like,
    "gripper_like.eds": gripper_like,
    "scanned_like.eds": scanned_like,
    "gocanopen_like.eds": gocanopen_like,
    "spaced_like.eds": spaced_like,
    "satellite_like.dcf": satellite_like,
    "editor_v4_like.eds": lambda: editor_v4_like("editor_v4_like.eds", False),
    "editor_v4_dup_like.eds": lambda: editor_v4_like("editor_v4_dup_like.eds", True),
    "ros_slave_like.eds": ros_slave_like,
    "legacy_node_like.eds": legacy_node_like,
    "editor_like.xdd": lambda: editor_xdd_like("editor_like.xdd", False),
    "editor_rtt_like.xdd": lambda: editor_xdd_like("editor_rtt_like.xdd", True),
}

if __name__ == "__main__":
    for file_name, make in FILES.items():
        write(file_name, make())
