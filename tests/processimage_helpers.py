"""Setup-file texts for the process-image tests, checksums computed as seed
004 §5.2 says (the sum of every byte of the entry, modulo 256)."""

from __future__ import annotations

from typing import Dict, List, Optional


def section(label: str, rows: List[str], checksum: Optional[str] = None) -> str:
    total = sum(sum(bytes.fromhex(row)) for row in rows) & 0xFF
    return f"[{label}]\n" + "\n".join(rows) + f"\n{checksum or f'{total:02X}'}\n"


#: A small device: node 0x40, 125 kbit/s, 8-byte image; TPDO 1 sends bytes
#: 0..1 ([6000,01..02], read-only), RPDO 1 writes bytes 2..3 ([6200,01..02]);
#: bytes 4..7 belong to no entry.
SECTIONS: Dict[str, List[str]] = {
    "ID": ["34120201"],
    "NODE": ["044008010100"],
    "RPDO": ["0000FF", "020203FFFFFFFFFFFF"],
    # COB-ID default, inhibit 0, event timer 0, type FEh (sent on change)
    "TPDO": ["0000" "0000" "0000" "FE", "020001FFFFFFFFFFFF"],
    "COD": ["4300100091010F00", "4F00600002000000", "4F00620002000000",
            "FFFFFFFFFFFFFFFF"],
    "RWOD": ["0060015100", "0060025101", "006201F102", "006202F103", "FFFFFFFFFF"],
    "PIMG": ["0011223344556677"],
}


def setup_text(header: str = "COPTSKA8 V1.0\n// process image test device\n",
               **replace: Optional[List[str]]) -> str:
    """The small device's file, sections replaced by keyword (None drops one)."""
    sections: Dict[str, Optional[List[str]]] = dict(SECTIONS, **replace)
    return header + "".join(section(label, rows) for label, rows in sections.items()
                            if rows is not None)
