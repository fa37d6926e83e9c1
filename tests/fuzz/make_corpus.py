#!/usr/bin/env python3
"""Writes the seed corpora of tests/fuzz (corpus/<harness>/seed-*): the
transfers, frame sequences and configuration steps of the C unit tests, in
the record format of fuzz_input.h. Run again after changing the format:
    python3 tests/fuzz/make_corpus.py
"""
import os
import struct
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))

# Actions of each harness, in the order of its actions[] table (fuzz_*.c).
ACTIONS = {
    "usdo_server": ["start", "cancel", "split", "resume", "nmt", "odw", "store", "start"],
    "usdo_client": ["start", "start", "cancel", "split", "resume", "nmt"],
    "sdo_server": ["start", "cancel", "split", "resume", "nmt", "odw", "store", "start"],
    "sdo_client": ["start", "start", "cancel", "split", "resume", "nmt", "odw"],
    "pdo": ["odw", "odw", "odput", "trigger", "nmt", "nmt_master", "emcy", "store", "start",
            "mpdo"],
    "services": ["nmt", "nmt_master", "emcy", "time", "watch", "watch", "odw", "odput", "store"],
    "stack": ["start", "cancel", "split", "resume", "nmt", "nmt_master", "odw", "odput",
              "trigger", "emcy", "time", "watch", "store", "led"],
    "gateway": ["switch", "tool", "own", "route", "timeout"],
}
# Frame CAN-ID tables (index = p of a FRAME record), as in fuzz_*.c.
IDS = {
    "usdo_server": [0x609, 0x601, 0x67F, 0x605, 0x000, 0x080, 0x585],
    "usdo_client": [0x585, 0x581, 0x5FF, 0x589, 0x605, 0x609],
    "sdo_server": [0x605, 0x600, 0x67F, 0x6A5, 0x000, 0x080, 0x585, 0x625],
    "sdo_client": [0x585, 0x581, 0x5FF, 0x605, 0x5A5],
    "pdo": [0x205, 0x305, 0x405, 0x505, 0x185, 0x285, 0x385, 0x485, 0x080, 0x000, 0x605, 0x609],
    "services": [0x000, 0x080, 0x100, 0x081, 0x082, 0x085, 0x703, 0x705, 0x701, 0x77F, 0x709,
                 0x0FF],
    "stack": [0x000, 0x080, 0x100, 0x085, 0x185, 0x205, 0x305, 0x585, 0x605, 0x609, 0x705,
              0x703, 0x6A5, 0x081],
    "gateway": [0x601, 0x585, 0x589, 0x605, 0x609, 0x581, 0x600, 0x67F],
}
# Client targets (fuzz_world.c targets[]) and configuration keys (config_keys[]).
T = {"id": 0, "devtype": 1, "hb": 2, "u8": 3, "u16": 4, "u32": 5, "i64": 6, "lim": 7,
     "vs": 8, "octet200": 9, "domain": 10, "bool": 11, "real": 12, "unicode": 13,
     "split": 14, "octet1024": 15, "wo": 16, "ro": 17, "save": 18, "restore": 19,
     "map": 20, "tpdo_cob": 21, "rpdo_cob": 22, "missing": 23}
K = {0x100500: 0, 0x100600: 1, 0x100700: 2, 0x100C00: 3, 0x100D00: 4, 0x101200: 5,
     0x101400: 6, 0x101500: 7, 0x101601: 8, 0x101602: 9, 0x101700: 10, 0x101900: 11,
     0x102801: 12, 0x102901: 13, 0x140001: 14, 0x140002: 15, 0x140003: 16, 0x140005: 17,
     0x160000: 18, 0x160001: 19, 0x160002: 20, 0x180001: 21, 0x180002: 22, 0x180003: 23,
     0x180005: 24, 0x180006: 25, 0x1A0000: 26, 0x1A0001: 27, 0x1A0002: 28, 0x120101: 29,
     0x128001: 30, 0x100300: 31, 0x1FA001: 32}


class Seq:
    def __init__(self, harness):
        self.h = harness
        self.b = bytearray()

    def frame(self, can_id, data=b"", raw_flags=None, other=False, length=None):
        p = IDS[self.h].index(can_id) if can_id in IDS[self.h] else 31
        n = len(data) if length is None else length
        fl = 0x80 | raw_flags if raw_flags is not None else (0x40 if other else 0)
        self.b += bytes([p << 3 | 0, fl, n])
        if p == 31:
            self.b += struct.pack("<H", can_id)
        if raw_flags is None or not raw_flags & 0x10:
            self.b += bytes(data)
        return self

    def time(self, ms):
        p = ms if ms < 16 else (15 + ms // 50 if ms < 450 else 23 + min(8, ms // 1000))
        self.b += bytes([min(p, 31) << 3 | 2])
        return self

    def act(self, name, *args, nth=0):
        have = [i for i, a in enumerate(ACTIONS[self.h]) if a == name]
        if not have:
            return self   # this harness does not offer the action: the step is left out
        idx = have[nth]
        self.b += bytes([idx << 3 | 3]) + bytes(args)
        return self

    def start(self, target, upload, mode=0, size=0, slot=0, flag8=False, other=False,
              sub=0, timeout=0, blk=0):
        f = (1 if upload else 0) | mode << 1 | (8 if flag8 else 0) | (0x10 if other else 0)
        f |= slot << 5
        args = [f, T[target], sub, size & 0xFF, size >> 8, timeout]
        if self.h in ("sdo_server", "sdo_client") or getattr(self, "classic", False):
            args.append(blk)
        return self.act("start", *args)

    def odw(self, key, value, pdo=0, name="odw"):
        return self.act(name, K[key], pdo, *struct.pack("<I", value))

    def bus(self, hold=False, mask=None, dup=False):
        p = (1 if hold else 0) | (2 if mask is not None else 0) | (4 if dup else 0)
        self.b += bytes([p << 3 | 4]) + (bytes([mask]) if mask is not None else b"")
        return self

    def process(self):
        self.b += bytes([5])
        return self

    def comm(self, event):
        self.b += bytes([(event - 1) << 3 | 6])
        return self

    def settle(self):
        self.b += bytes([7])
        return self


def write(harness, seeds):
    d = os.path.join(HERE, "corpus", harness)
    os.makedirs(d, exist_ok=True)
    for f in os.listdir(d):
        if f.startswith("seed-"):
            os.remove(os.path.join(d, f))
    for name, data in seeds.items():
        with open(os.path.join(d, "seed-" + name), "wb") as f:
            f.write(bytes(data))


def server_seeds(h, classic):
    S = lambda: Seq(h)
    seeds = {
        "upload-identity": S().start("id", True).time(5),
        "download-u16": S().start("u16", False, mode=1 if not classic else 1, size=2).time(5)
                           .start("u16", True).time(5),
        "segmented-octet": S().start("octet1024", False, mode=2, size=1000).time(20)
                              .start("octet1024", True, slot=1).time(20),
        "big-domain": S().start("domain", False, mode=3, size=5000).time(50)
                         .start("domain", True, slot=2).time(50),
        "split-answer": S().act("split", 1).start("split", True).time(2).act("resume", 0)
                           .time(5).start("split", False, mode=1, size=4).time(2)
                           .act("resume", 0x10).time(5),
        "split-abandoned": S().act("split", 1).start("split", True, timeout=5).time(200)
                              .act("resume", 0).time(5),
        "reset-midway": S().start("octet1024", True, mode=0).bus(hold=True).time(1)
                           .act("nmt", 3).bus(hold=True).time(5).settle(),
        "limits-and-save": S().start("lim", False, mode=1, size=2).time(2)
                              .start("save", False, mode=1, size=4).time(2)
                              .act("store", 0x47).time(2),
        "lossy": S().start("octet200", False, mode=2, size=200).bus(mask=0x24).time(400)
                    .start("octet200", True, slot=3).bus(mask=0x11, dup=True).time(400),
        "two-at-once": S().start("octet1024", True, slot=0).start("vs", False, mode=2, size=20,
                                                                  slot=1).time(10),
    }
    if classic:
        seeds["raw-expedited-upload"] = (S().frame(0x605, [0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0])
                                         .time(1).frame(0x605, [0x40, 0x18, 0x10, 0x04, 0, 0, 0, 0])
                                         .time(1))
        seeds["raw-block-download"] = (S().frame(0x605, [0xC6, 0x01, 0x21, 0x00, 0x0A, 0, 0, 0])
                                       .time(1).frame(0x605, [0x01, 1, 2, 3, 4, 5, 6, 7])
                                       .frame(0x605, [0x82, 8, 9, 10, 0, 0, 0, 0]).time(1)
                                       .frame(0x605, [0xC9, 0, 0, 0, 0, 0, 0, 0]).time(1))
        seeds["block-crc"] = S().start("octet1024", False, mode=3, size=900, blk=0x20).time(20) \
            .start("octet1024", True, mode=3, slot=1, blk=0x85, sub=3).time(20)
        seeds["channel-1"] = S().odw(0x120101, 0x6A5).time(1).frame(
            0x6A5, [0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]).time(1)
    else:
        seeds["raw-upload"] = S().frame(0x609, [0x05, 0x11, 0x02, 0x01, 0x18, 0x10]).time(1) \
            .frame(0x609, [0x05, 0x11, 0x03, 0x00, 0x00, 0x21]).time(1)
        seeds["broadcast"] = S().start("devtype", True, flag8=True).time(1100)
        # bulk upload (0x16 / 0x17 requests; 0x36 / 0x37 / 0x38 answers), our layout
        seeds["bulk-upload"] = S().start("octet1024", False, mode=2, size=1000).time(20) \
            .start("octet1024", True, mode=3, slot=1).time(50)
        seeds["bulk-upload-auto-hint"] = S().start("domain", True, mode=0, size=5000).time(80)
        seeds["bulk-upload-lossy"] = S().start("domain", True, mode=3).bus(mask=0x24).time(400)
        seeds["raw-bulk-upload"] = (
            S().frame(0x609, [0x05, 0x16, 0x04, 0x00, 0x00, 0x21, 0x04, 0x00]).time(1)
            .frame(0x609, [0x05, 0x17, 0x04, 0x01]).time(1)
            .frame(0x609, [0x05, 0x17, 0x04, 0x09]).time(1)
            .frame(0x609, [0x05, 0x16, 0x05, 0x00, 0x00, 0x21, 0x00, 0x00]).time(1)
            .frame(0x609, [0x05, 0x17, 0x33, 0x00]).time(1))
        seeds["raw-short-segments"] = (
            S().frame(0x609, [0x05, 0x02, 0x06, 0x00, 0x00, 0x21, 0x0F, 0, 100, 0, 0, 0]).time(1)
            .frame(0x609, [0x05, 0x03, 0x06, 0x00] + list(range(28))).time(1)
            .frame(0x609, [0x05, 0x03, 0x06, 0x01] + list(range(44))).time(1)
            .frame(0x609, [0x05, 0x04, 0x06, 28] + list(range(28))).time(1))
    return seeds


def client_seeds(h, classic):
    S = lambda: Seq(h)
    seeds = server_seeds(h, classic)
    answer = 0x585
    seeds["forged-answers"] = (S().start("octet1024", True, mode=2).frame(answer, [9, 0x31, 1, 0, 0x01, 0x21, 4, 0, 1, 2, 3, 4] if not classic else [0x43, 0x01, 0x21, 0, 1, 2, 3, 4])
                               .time(1).frame(answer, [0x80, 0, 0, 0, 0, 0, 4, 5] if classic else [9, 0x7F, 1, 0x12]).time(400))
    if not classic:
        # a bulk upload answered by hand: 0x36, a short 0x37, 0x38; an empty 0x31 (N = 0)
        seeds["forged-bulk-upload"] = (
            S().start("octet1024", True, mode=3)
            .frame(answer, [9, 0x36, 1, 0, 0x00, 0x21, 0x0A, 0, 70, 0, 0, 0]).time(1)
            .frame(answer, [9, 0x37, 1, 0] + list(range(28))).time(1)
            .frame(answer, [9, 0x37, 1, 1] + list(range(60))).time(1)
            .frame(answer, [9, 0x38, 1, 0]).time(400))
        seeds["forged-empty-expedited"] = (
            S().start("vs", True).frame(answer, [9, 0x31, 1, 0, 0x00, 0x21, 0x09, 0]).time(5))
    seeds["timeout"] = S().start("id", True, other=True, timeout=10).time(200).start(
        "u8", False, mode=1, size=1, other=True).time(1000)
    seeds["cancel"] = S().start("octet1024", False, mode=2, size=1000).time(1).act(
        "cancel", 0).time(5).start("octet1024", True).act("cancel", 4).time(5)
    seeds["held-bus-bulk"] = S().start("domain", False, mode=3, size=6000).bus(hold=True).time(
        2).bus(hold=True).time(20)
    return seeds


def pdo_seeds():
    seeds = {}
    for classic in (False, True):
        m = "classic" if classic else "fd"
        S = lambda: Seq("pdo")
        def head(s):
            s.b += bytes([1 if classic else 0])
            s.classic = classic
            return s
        n = 8 if classic else 16
        seeds[m + "-rpdo"] = (head(S()).act("nmt", 0).time(1).frame(0x205, [0x22, 0x11])
                              .frame(0x305, [1, 2, 3, 4]).frame(0x080, []).time(1)
                              .frame(0x205, [0x22]).frame(0x205, bytes(n)).time(600))
        seeds[m + "-remap"] = (head(S()).act("nmt", 0).time(1)
                               .odw(0x140001, 0x80000205).odw(0x160000, 0)
                               .odw(0x160001, 0x20020020).odw(0x160002, 0x20000008)
                               .odw(0x160000, 2).odw(0x140001, 0x205).frame(0x205, [1, 2, 3, 4, 5])
                               .time(1).odw(0x160001, 0x20060040, pdo=3).time(1))
        seeds[m + "-tpdo"] = (head(S()).act("nmt", 0).act("trigger", 0).act("trigger", 0x81)
                              .time(15).frame(0x080, [1]).frame(0x080, [2]).time(1)
                              .frame(0x385, raw_flags=0x10, length=4).time(1)
                              .odw(0x180001, 0x80000185).odw(0x1A0001, 0x20010010)
                              .odw(0x180001, 0x185).odw(0x180005, 20).time(100))
        seeds[m + "-sync-producer"] = (head(S()).act("nmt", 0).odw(0x101900, 4)
                                       .odw(0x100600, 10000).odw(0x100500, 0x40000080)
                                       .time(100).odw(0x100700, 5000).time(100))
        # MPDOs (co_mpdo): RPDO 1 made a DAM, then a SAM consumer by the CiA 301 procedure;
        # frames for this node (5), all, another node, a missing object, the wrong mode,
        # the wrong length; then TPDO 1 and 2 made SAM producers (the second refused)
        def make_mpdo(s, marker):
            return (s.odw(0x140001, 0x80000205).odw(0x160000, 0).odw(0x160000, marker)
                    .odw(0x140002, 254).odw(0x140001, 0x205))
        dam = [0x85, 0x02, 0x20, 0x00, 0x44, 0x33, 0x22, 0x11]
        sam = [0x07, 0x02, 0x20, 0x00, 0x78, 0x56, 0x34, 0x12]
        seeds[m + "-mpdo-dam"] = (make_mpdo(head(S()).act("nmt", 0).time(1), 0xFF)
                                  .frame(0x205, dam).frame(0x205, [0x80] + dam[1:])
                                  .frame(0x205, [0x87] + dam[1:]).time(1)
                                  .frame(0x205, [0x85, 0xFF, 0x2F, 0x00, 1, 0, 0, 0])
                                  .frame(0x205, [0x85, 0x06, 0x20, 0x00, 1, 2, 3, 4])
                                  .frame(0x205, sam).frame(0x205, dam[:4])
                                  .frame(0x205, dam + dam).time(5))
        # (the device's dispatcher list takes node 7's 0x2002:00 and 0x2001:00; its
        # scanner list names 0x2002:00 and 0x2001:00, then 0x2100:00)
        seeds[m + "-mpdo-sam"] = (make_mpdo(head(S()).act("nmt", 0).time(1), 0xFE)
                                  .frame(0x205, sam).frame(0x205, dam).frame(0x205, sam[:7])
                                  .frame(0x205, [0x07, 0x01, 0x20, 0x00, 0x34, 0x12, 0, 0])
                                  .frame(0x205, [0x09] + sam[1:])
                                  .time(1).odw(0x180001, 0x80000185).odw(0x1A0000, 0)
                                  .odw(0x1A0000, 0xFE).odw(0x180001, 0x80000285, pdo=1)
                                  .odw(0x1A0000, 0, pdo=1).odw(0x1A0000, 0xFE, pdo=1)
                                  .act("trigger", 0).act("trigger", 0x81)
                                  .odw(0x180001, 0x185).time(2)           # TPDO 1 on again
                                  .act("mpdo", 0x80, 0, 0, 0, 0, 0).time(2)   # SAM 0x2002:00
                                  .act("mpdo", 0x8C, 0, 0, 0, 0, 0).time(2)   # 0x2103: unlisted
                                  .odw(0x1FA001, 0x01210000)
                                  .act("mpdo", 0x88, 0, 0, 0, 0, 0).time(5))   # now listed
        # DAM producer: TPDO 1 made a DAM, its mapped object and a value of our own
        seeds[m + "-mpdo-dam-send"] = (head(S()).act("nmt", 0).time(1)
                                       .odw(0x180001, 0x80000185).odw(0x1A0000, 0)
                                       .odw(0x1A0000, 0xFF).odw(0x180001, 0x185)
                                       .act("mpdo", 0x40, 9, 0, 0, 0, 0).time(2)
                                       .act("mpdo", 0x24, 0, 0x78, 0x56, 0x34, 0x12).time(2)
                                       .act("mpdo", 0x01, 9, 1, 0, 0, 0).time(5))
        seeds[m + "-states"] = (head(S()).act("nmt", 0).frame(0x205, [3, 4]).act("nmt", 1)
                                .frame(0x205, [5, 6]).time(1).act("nmt_master", 0x80).time(1)
                                .act("store", 0x07).act("nmt", 3).time(5))
    return seeds


def services_seeds():
    seeds = {}
    for classic in (False, True):
        m = "classic" if classic else "fd"
        S = lambda: Seq("services")
        def head(s):
            s.b += bytes([1 if classic else 0])
            return s
        emcy = [0x10, 0x81, 0x11, 1, 2, 3, 4, 5] if classic else \
            [0x10, 0x81, 0x11, 0x2D, 0x01, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]
        seeds[m + "-heartbeat"] = (head(S()).act("watch", 0, 3, 25).frame(0x703, [0])
                                   .frame(0x703, [5]).time(50).time(200).frame(0x703, [0x7F])
                                   .frame(0x703, [4, 4]).time(5).odw(0x101700, 20)
                                   .act("watch", 0, 5, 10).time(200))
        seeds[m + "-emcy"] = (head(S()).act("watch", 2, 5, 0).act("watch", 2, 1, 0)
                              .frame(0x081, emcy).frame(0x085, emcy[:4]).time(1)
                              .act("emcy", 0x01, 0x10, 0x81).time(1).act("emcy", 0x09, 0x10, 0x81)
                              .time(1).act("emcy", 0x18, 0, 0).time(1))
        seeds[m + "-sync-time"] = (head(S()).frame(0x080, []).frame(0x080, [1]).frame(0x080, [1, 2])
                                   .frame(0x100, [0, 0, 0, 0, 0x10, 0x27]).time(1)
                                   .act("time", 0, 1, 2, 3, 4).act("time", 1, 5, 6, 7, 8).time(1)
                                   .odw(0x101200, 0x40000100).act("time", 0, 9, 9, 9, 9).time(1))
        seeds[m + "-nmt"] = (head(S()).frame(0x000, [0x01, 5], other=True).time(1)
                             .frame(0x000, [0x80, 0], other=True).frame(0x000, [0x99, 5], other=True)
                             .frame(0x000, [0x02], other=True).time(1).act("nmt_master", 0x03)
                             .time(5).act("nmt_master", 0x84).time(5).act("nmt", 4).time(5))
        if classic:
            seeds["classic-guarding"] = (head(S()).odw(0x100C00, 20).odw(0x100D00, 3)
                                         .act("watch", 0x34, 5, 20).time(100)
                                         .act("watch", 0x06, 5, 5).time(100).act("watch", 5, 5, 0)
                                         .frame(0x705, raw_flags=0x10, length=1, other=True)
                                         .time(200))
    return seeds


def stack_seeds():
    seeds = {}
    for classic in (False, True):
        m = "classic" if classic else "fd"
        S = lambda: Seq("stack")
        def head(s):
            s.b += bytes([1 if classic else 0])
            s.classic = classic
            return s
        seeds[m + "-boot-serve"] = (head(S()).time(5).start("id", True).time(5)
                                    .act("nmt_master", 0).time(1).frame(0x205, [1, 2]).time(1)
                                    .act("trigger", 0x81).time(2))
        seeds[m + "-errors"] = (head(S()).comm(1).time(1).comm(11).comm(2).comm(3).comm(4)
                                .time(1).act("emcy", 0x01, 0x00, 0x50).time(1))
        seeds[m + "-store-reset"] = (head(S()).odw(0x101700, 30).start("save", False, mode=1,
                                                                      size=4).time(2)
                                     .act("nmt", 3).time(40).act("store", 0x81).act("nmt", 3)
                                     .time(40))
        # LEDs: LSS flickering, the application's causes, NMT and comm events under them
        seeds[m + "-leds"] = (head(S()).time(100).act("led", 0x81).time(120).act("led", 0x80)
                              .act("led", 0x20, 0x20).time(450).act("nmt_master", 0)
                              .time(50).comm(2).time(450).act("led", 0x3F, 0x1C).time(1000)
                              .act("nmt_master", 1).comm(3).act("led", 0x3F, 0).time(1000))
    return seeds


def store_seeds():
    def record(key, typ, value):
        return struct.pack("<IBI", key, typ, len(value)) + value
    recs = [record(0x101700, 0x06, struct.pack("<H", 250)),
            record(0x140001, 0x07, struct.pack("<I", 0x80000207)),
            record(0x200000, 0x01, b"\x00"),
            record(0x200100, 0x03, struct.pack("<h", -50)),
            record(0x200200, 0x08, struct.pack("<f", 0.5)),
            record(0x200300, 0x09, b"hello"),
            record(0x200400, 0x0B, b"a\x00b\x00"),
            record(0x200500, 0x0A, bytes(range(40))),
            record(0x200600, 0x1B, struct.pack("<Q", 1 << 40)),
            record(0x600000, 0x10, b"\x01\x02\x03"),
            record(0x600100, 0x07, struct.pack("<I", 5000)),
            record(0xA00000, 0x05, b"\x07")]

    def image(records):
        payload = b"".join(records)
        head = b"CoFDpar\x00" + struct.pack("<HHIII", 1, 28, 0x12345678, len(records),
                                           len(payload))
        crc = zlib.crc32(payload, zlib.crc32(head))
        return head + struct.pack("<I", crc) + payload
    return {
        "full": bytes([0]) + image(recs),
        "one-group": bytes([0x20]) + image(recs),
        "refused-values": bytes([0]) + image([record(0x200000, 0x01, b"\x02"),
                                              record(0x200100, 0x03, struct.pack("<h", 500)),
                                              record(0x200400, 0x0B, b"abc"),
                                              record(0x200800, 0x05, b"\x01"),
                                              record(0x300000, 0x05, b"\x01")]),
        "fixed-header": bytes([3]) + image(recs[:3])[:40],
        "empty": bytes([0]) + image([]),
    }


def concise_dcf_seeds():
    def dcf(entries, count=None):
        body = b"".join(struct.pack("<HBI", i, s, len(v)) + v for i, s, v in entries)
        return struct.pack("<I", len(entries) if count is None else count) + body
    good = [(0x1017, 0, struct.pack("<H", 1000)), (0x1800, 1, struct.pack("<I", 0x80000185)),
            (0x1A00, 0, b"\x00"), (0x1A00, 1, struct.pack("<I", 0x60000108)),
            (0x1A00, 0, b"\x01"), (0x1800, 1, struct.pack("<I", 0x185)),
            (0x2000, 0, b"config text"), (0x2001, 0, b"")]
    return {
        "pdo-config": dcf(good),
        "empty": dcf([]),
        "count-mismatch": dcf(good[:2], count=3),
        "trailing": dcf(good[:2]) + b"\x01\x02",
        "size-past-end": dcf(good[:2])[:-1],
    }


def gateway_seeds():
    """SDO networking through the gateway (fuzz_gateway.c): raw indications
    and relayed transfers, a route via node 9 answered by hand, the tool's
    routed requests, the gateway's own client beside the relay, timeouts."""
    def S():
        return Seq("gateway")
    ind = lambda net, node: [0xE0, net, 0, node, 0, 0, 0, 0]
    up = [0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0]
    up_ok = [0x43, 0x00, 0x20, 0x00, 0x78, 0x56, 0x34, 0x12]
    seeds = {}
    seeds["attached-relay"] = (S().frame(0x601, ind(3, 5)).process().frame(0x601, up).time(5)
                               .frame(0x601, [0x23, 0x00, 0x20, 0x00, 1, 2, 3, 4]).time(5)
                               .frame(0x601, [0x80, 0x00, 0x20, 0x00, 0, 0, 0, 5]).time(5)
                               .frame(0x601, ind(0, 0)).time(5))
    seeds["via-next-gateway"] = (S().frame(0x601, ind(7, 5)).process()
                                 .frame(0x589, ind(7, 5), other=True).process()
                                 .frame(0x601, up).process()
                                 .frame(0x589, up_ok, other=True).time(5)
                                 .frame(0x601, up).time(450))
    seeds["via-refused"] = (S().frame(0x601, ind(7, 5)).process()
                            .frame(0x589, [0x80, 7, 0, 5, 0x23, 0, 0x0A, 6], other=True).time(5)
                            .frame(0x601, ind(7, 5)).time(450))
    seeds["both-clients"] = (S().frame(0x601, ind(3, 5)).act("switch").frame(0x601, ind(3, 5))
                             .frame(0x601, ind(1, 9)).act("switch").frame(0x601, up).time(5)
                             .act("switch").frame(0x601, ind(2, 7)).time(5))
    seeds["tool-routed"] = (S().act("tool", 3, 5, 0x40).time(20).act("tool", 3, 5, 0x41).time(20)
                            .act("tool", 0, 0, 0x00).time(20).act("tool", 9, 5, 0x40).time(20)
                            .act("tool", 7, 5, 0x46).process()
                            .frame(0x589, ind(7, 5), other=True).time(450))
    seeds["own-client-beside"] = (S().act("own", 5, 0x00).frame(0x601, ind(3, 5)).time(5)
                                  .act("own", 5, 0x04).frame(0x601, up).time(5)
                                  .act("own", 9, 0x00).time(400))
    seeds["routes-timeout"] = (S().act("route", 8, 3, 9).act("route", 9, 8, 9)
                               .act("route", 8, 9, 9).act("timeout", 10, 0)
                               .frame(0x601, ind(9, 5)).time(20).frame(0x601, ind(8, 5))
                               .time(20).settle())
    seeds["garbage"] = (S().frame(0x601, [0xE0, 3, 0, 5], length=4)
                        .frame(0x601, [0xE0, 0xFF, 0xFF, 200, 0, 0, 0, 0])
                        .frame(0x601, [0xFF] * 8).frame(0x605, up, raw_flags=0x04)
                        .frame(0x601, up, raw_flags=0x02, length=8).time(5))
    return seeds


def srdo_seeds():
    """fuzz_srdo.c: byte 0 bit 0 = classic; actions by number (p): even p acts on
    the consumer, odd on the producer; (p >> 1) % 7 = nmt, configure, data,
    restart, gfc on/off, gfc send, fail."""
    def frame(p, data):
        return bytes([p << 3, 0, len(data)]) + data

    def time(ms):
        return bytes([ms << 3 | 2])

    def act(p, *args):
        return bytes([p << 3 | 3]) + bytes(args)

    good = bytes([0x12, 0x34, 0x56, 0x78])
    inv = bytes(b ^ 0xFF for b in good)
    mapping = bytes([0x20, 0x20] + [0] * 14)
    return {
        "pairs": b"\x01" + act(0, 1) + act(1, 1) + time(20) + time(20) + time(20),
        "inject": b"\x01" + act(0, 1) + frame(0, good) + time(1) + frame(1, inv) + time(10)
        + frame(0, good) + frame(1, inv[:3] + b"\0") + time(5),
        "gfc": b"\x00" + act(0, 1) + act(8, 1) + act(9, 1) + act(11) + time(3) + act(6)
        + time(2),
        "config": b"\x01" + act(2, 0x3F, 0, 0, 0, 2) + mapping + bytes([1, 0xA5, 1, 0])
        + act(0, 1) + time(16),
    }


def cia402_sim_seeds():
    """fuzz_cia402_sim.c: byte 0 = the drive's 0x6502 (0: no object); actions by
    number (p % 8): 0 controlword over SDO, 1 controlword by RPDO, 2 an object
    over SDO, 3 an object by RPDO (index into writable[], then 4 value bytes),
    4 SYNC, 5 fault (2 code bytes), 6 one model step (2 bytes of us), 7 the
    mode over SDO. A controlword argument below 200 picks a common one:
    0x00, 0x02, 0x06, 0x07, 0x0F, 0x1F, 0x3F, 0x5F, 0x80, 0x10F, 0x0B, 0x86."""
    cw = {0x00: 0, 0x02: 1, 0x06: 2, 0x07: 3, 0x0F: 4, 0x1F: 5, 0x3F: 6, 0x5F: 7, 0x80: 8,
          0x10F: 9}
    obj = {0x6040: 0, 0x6060: 1, 0x607A: 2, 0x60FF: 3, 0x6071: 4, 0x6081: 5, 0x6083: 6,
           0x6084: 7, 0x6098: 8}

    def act(p, *args):
        return bytes([p << 3 | 3]) + bytes(args)

    def time(ms):
        return bytes([ms << 3 | 2])

    def sdo_cw(word):
        return act(0, cw[word])

    def pdo_cw(word):
        return act(1, cw[word])

    def sdo(index, value):
        return act(2, obj[index]) + struct.pack("<i", value)

    def pdo(index, value):
        return act(3, obj[index]) + struct.pack("<i", value)

    def mode(m):
        return act(7, m & 0xFF)

    enable = sdo_cw(0x06) + sdo_cw(0x07) + sdo_cw(0x0F)
    sync = act(4, 0)
    return {
        # every transition over SDO: enable, disable operation, quick stop, disable voltage
        "power": b"\x00" + enable + sdo_cw(0x07) + sdo_cw(0x0F) + sdo_cw(0x02) + time(2)
        + sdo_cw(0x0F) + sdo_cw(0x06) + sdo_cw(0x00) + time(1),
        # the cyclic RPDO path: commands by RPDO, taken at the next tick or SYNC
        "rpdo-enable": b"\x00" + mode(8) + pdo_cw(0x06) + sync + pdo_cw(0x07) + time(1)
        + pdo_cw(0x0F) + sync + pdo(0x607A, 500) + sync + pdo(0x607A, -500) + sync,
        # profile position: set-points with and without bit 5, relative, halt
        "pp-moves": b"\xA5" + mode(1) + enable + sdo(0x607A, 2000) + sdo_cw(0x1F) + time(5)
        + sdo_cw(0x0F) + sdo(0x607A, 100) + sdo_cw(0x1F) + sdo_cw(0x0F) + sdo_cw(0x5F)
        + time(26) + sdo_cw(0x10F) + time(20),
        # profile velocity, homing, CSV/CST at SYNCs
        "pv-homing-csv": b"\xA5" + mode(3) + enable + sdo(0x60FF, -3000) + time(18) + mode(6)
        + sdo_cw(0x1F) + time(1) + mode(9) + pdo(0x60FF, 12345) + sync + sync + mode(10)
        + pdo(0x6071, -77) + sync,
        # a fault mid-move, a reset by RPDO and by SDO, an unsupported mode refused
        "fault": b"\x25" + mode(1) + enable + sdo(0x607A, 900000) + sdo_cw(0x1F) + time(3)
        + act(5, 0x21, 0x71) + time(1) + pdo_cw(0x80) + time(1) + sdo_cw(0x00) + sdo_cw(0x80)
        + mode(10) + enable + act(6, 0xE8, 0x03),
    }


def cia401_seeds():
    """fuzz_cia401.c: byte 0 unused; frames by table index (0 NMT, 1 SYNC, 2 RPDO1,
    3 RPDO2, 4 SDO request); actions by number (p % 5): 0 set_inputs (first, count,
    3 raw bytes), 1 set_analog_input (channel, 2 value bytes), 2 fault, 3 an SDO
    download, 4 the application's write (both: objects[] pick, then 4 value bytes;
    pick bits 5..7 choose the sub)."""
    obj = {0x6000: 0, 0x6002: 1, 0x6005: 3, 0x6006: 4, 0x6200: 7, 0x6202: 8, 0x6206: 9,
           0x6207: 10, 0x6208: 11, 0x6411: 13, 0x6421: 14, 0x6423: 15, 0x6426: 18,
           0x6443: 21, 0x6444: 22}

    def frame(p, data):
        return bytes([p << 3, 0, len(data)]) + bytes(data)

    def act(p, *args):
        return bytes([p << 3 | 3]) + bytes(args)

    def sdo(index, value, sub_bits=0):
        return act(3, obj[index] | sub_bits << 5) + struct.pack("<i", value)

    def put(index, value, sub_bits=0):
        return act(4, obj[index] | sub_bits << 5) + struct.pack("<i", value)

    start, stop, reset = frame(0, [1, 5]), frame(0, [2, 5]), frame(0, [0x81, 5])
    return {
        # inputs in pre-operational and operational, a polarity, the global enable
        "inputs": b"\x00" + act(0, 1, 2, 1, 0x80, 0) + start + act(0, 1, 2, 3, 0x80, 0)
        + sdo(0x6002, 0x0F) + act(0, 2, 1, 0x55, 0, 0) + sdo(0x6005, 0) + act(0, 1, 2, 0, 0, 0)
        + act(0, 3, 1, 1, 0, 0) + bytes([2 << 3 | 2]),
        # analogue inputs: delta and limits
        "analog": b"\x00" + start + sdo(0x6423, 1) + sdo(0x6426, 100) + act(1, 1, 50, 0)
        + act(1, 1, 0x88, 0xFF) + sdo(0x6421, 0x1F) + act(1, 1, 0xE8, 0x03) + act(1, 2, 0, 0),
        # outputs by SDO, RPDO1, RPDO2 and the application
        "outputs": b"\x00" + start + sdo(0x6202, 1) + sdo(0x6200, 0x0F) + sdo(0x6208, 0xF0)
        + frame(2, [0x33]) + frame(3, [0xD4, 0xFE, 0x34, 0x12]) + put(0x6411, 7, 1),
        # error values on NMT stop and on a fault, then a reset node
        "fault": b"\x00" + start + sdo(0x6206, 0x0F) + sdo(0x6207, 5) + sdo(0x6443, 0, 1)
        + sdo(0x6444, 100000) + sdo(0x6200, 0xF2) + sdo(0x6411, 100) + stop + act(2)
        + act(0, 1, 2, 1, 3, 0) + reset + bytes([5 << 3 | 2]) + act(2),
    }


def main():
    for h in ("usdo_server", "sdo_server"):
        write(h, {k: v.b for k, v in server_seeds(h, h.startswith("sdo")).items()})
    for h in ("usdo_client", "sdo_client"):
        write(h, {k: v.b for k, v in client_seeds(h, h.startswith("sdo")).items()})
    write("pdo", {k: v.b for k, v in pdo_seeds().items()})
    write("services", {k: v.b for k, v in services_seeds().items()})
    write("stack", {k: v.b for k, v in stack_seeds().items()})
    write("store", store_seeds())
    write("concise_dcf", concise_dcf_seeds())
    write("gateway", {k: v.b for k, v in gateway_seeds().items()})
    write("srdo", srdo_seeds())
    write("cia402_sim", cia402_sim_seeds())
    write("cia401", cia401_seeds())


if __name__ == "__main__":
    main()
