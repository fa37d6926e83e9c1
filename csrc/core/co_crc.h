/* Checksums of the core: CRC-32 of stored parameter images (co_store) and
 * the CRC-16-CCITT of SDO block transfer (co_sdo_server, SDO clients). Pure
 * functions over const tables: no state, usable from any thread and on bare
 * metal. */
#ifndef CO_CRC_H
#define CO_CRC_H

#include <stddef.h>
#include <stdint.h>

/* CRC-32 (IEEE 802.3, reflected, polynomial 0xEDB88320, init and xorout
 * 0xFFFFFFFF). Chains like zlib's crc32(): start with crc = 0 and pass the
 * previous result to go on, so co_crc32(co_crc32(0, a, n), b, m) is the CRC of
 * a followed by b. The check value of "123456789" is 0xCBF43926. */
uint32_t co_crc32(uint32_t crc, const uint8_t *data, size_t length);

/* CRC-16-CCITT as CiA 301 SDO block transfer uses it: polynomial
 * x^16 + x^12 + x^5 + 1 (0x1021), initial value 0x0000, bits taken most
 * significant first (no reflection), no final XOR ("CRC-16/XMODEM"; the
 * same table and init 0 as CANopenNode's crc16_ccitt). Chains: start with
 * crc = 0 and pass the previous result to go on, so
 * co_crc16_ccitt(co_crc16_ccitt(0, a, n), b, m) is the CRC of a followed by
 * b. The check value of "123456789" is 0x31C3; the CRC of nothing is 0. */
uint16_t co_crc16_ccitt(uint16_t crc, const uint8_t *data, size_t length);

#endif
