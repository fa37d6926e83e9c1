#include "canopenfd/co_emcy_codec.h"

#include <string.h>

/* Bytes 0..7: common to both formats. */
static void put_common(const co_emcy_msg_t *msg, uint8_t *out)
{
    out[0] = (uint8_t)(msg->code & 0xFFu);
    out[1] = (uint8_t)(msg->code >> 8);
    out[2] = msg->error_register;
    memcpy(out + 3, msg->msef, CO_EMCY_MSEF_LEN);
}

static void get_common(const uint8_t *data, co_emcy_msg_t *out)
{
    memset(out, 0, sizeof *out);
    out->code = (uint16_t)(data[0] | (data[1] << 8));
    out->error_register = data[2];
    memcpy(out->msef, data + 3, CO_EMCY_MSEF_LEN);
}

size_t co_emcy_encode_classic(const co_emcy_msg_t *msg, uint8_t *out, size_t cap)
{
    if (msg == NULL || out == NULL || cap < CO_EMCY_CLASSIC_LEN) {
        return 0;
    }
    put_common(msg, out);
    return CO_EMCY_CLASSIC_LEN;
}

bool co_emcy_decode_classic(const uint8_t *data, size_t len, co_emcy_msg_t *out)
{
    /* CiA 301: the EMCY is 8 bytes; shorter or longer frames are refused
     * (no guessing at missing fields). */
    if (data == NULL || out == NULL || len != CO_EMCY_CLASSIC_LEN) {
        return false;
    }
    get_common(data, out);
    return true;
}

size_t co_emcy_encode_fd(const co_emcy_msg_t *msg, uint8_t *out, size_t cap)
{
    if (msg == NULL || out == NULL || cap < CO_EMCY_FD_LEN ||
        msg->time_stamp > CO_EMCY_TIME_MAX) {
        return 0;
    }
    put_common(msg, out);
    out[8] = msg->logical_device;
    out[9] = (uint8_t)(msg->spec_number & 0xFFu);
    out[10] = (uint8_t)(msg->spec_number >> 8);
    out[11] = msg->status;
    for (unsigned i = 0; i < 6; i++) {
        out[12 + i] = (uint8_t)(msg->time_stamp >> (8 * i));
    }
    out[18] = 0;
    out[19] = 0;
    return CO_EMCY_FD_LEN;
}

bool co_emcy_decode_fd(const uint8_t *data, size_t len, co_emcy_msg_t *out)
{
    if (data == NULL || out == NULL || len < CO_EMCY_FD_LEN) {
        return false;
    }
    get_common(data, out);
    out->logical_device = data[8];
    out->spec_number = (uint16_t)(data[9] | (data[10] << 8));
    out->status = data[11];
    for (unsigned i = 0; i < 6; i++) {
        out->time_stamp |= (uint64_t)data[12 + i] << (8 * i);
    }
    return true;
}

uint8_t co_emcy_code_register_bits(uint16_t code)
{
    switch (code >> 12) {
    case 0x2:
        return CO_EMCY_ER_CURRENT;
    case 0x3:
        return CO_EMCY_ER_VOLTAGE;
    case 0x4:
        return CO_EMCY_ER_TEMPERATURE;
    case 0x8:
        /* 0x80xx monitoring, 0x81xx communication, 0x82xx protocol error;
         * 0x83xx.. are device-profile monitoring codes (CiA 402 etc.). */
        return (code >> 8) <= 0x82u ? CO_EMCY_ER_COMMUNICATION : 0;
    case 0xF:
        return (code >> 8) == 0xFFu ? CO_EMCY_ER_MANUFACTURER : 0;
    default:
        return 0;
    }
}
