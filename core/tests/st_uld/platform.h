/* depthor's platform layer for ST's VL53L5CX ULD, used only by core/tests/st_uld_crosscheck.rs.
 * ST's sources (downloaded at test time, never committed) include "platform.h"; this one routes
 * every register access to callbacks set by the Rust test, which forward them to the simulated
 * sensor. Written for depthor (MIT OR Apache-2.0); only the function names and signatures
 * follow ST's platform interface. */
#ifndef DEPTHOR_ULD_PLATFORM_H
#define DEPTHOR_ULD_PLATFORM_H

#include <stdint.h>
#include <string.h>

/* One target per zone, every output enabled: ULD's defaults, which the Rust driver mirrors. */
#define VL53L5CX_NB_TARGET_PER_ZONE 1U

typedef struct {
	uint16_t address; /* 8-bit form, as ST passes it around */
} VL53L5CX_Platform;

uint8_t RdByte(VL53L5CX_Platform *p, uint16_t index, uint8_t *value);
uint8_t WrByte(VL53L5CX_Platform *p, uint16_t index, uint8_t value);
uint8_t RdMulti(VL53L5CX_Platform *p, uint16_t index, uint8_t *values, uint32_t size);
uint8_t WrMulti(VL53L5CX_Platform *p, uint16_t index, uint8_t *values, uint32_t size);
uint8_t Reset_Sensor(VL53L5CX_Platform *p);
void SwapBuffer(uint8_t *buffer, uint16_t size);
uint8_t WaitMs(VL53L5CX_Platform *p, uint32_t ms);

#endif
