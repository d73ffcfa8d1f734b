/* depthor's test shim around ST's VL53L5CX ULD: the platform functions (bus access through
 * callbacks into the Rust test) and one entry point that runs ST's driver through the same
 * sequence as the Rust driver's test. Written for depthor (MIT OR Apache-2.0). */
#include <stddef.h>
#include "vl53l5cx_api.h"

typedef int (*depthor_rd_fn)(uint8_t addr7, uint16_t index, uint8_t *buf, uint32_t len);
typedef int (*depthor_wr_fn)(uint8_t addr7, uint16_t index, const uint8_t *buf, uint32_t len);
typedef void (*depthor_frame_fn)(uint32_t frame);

static depthor_rd_fn bus_rd;
static depthor_wr_fn bus_wr;
static uint64_t waited_ms;

uint8_t RdMulti(VL53L5CX_Platform *p, uint16_t index, uint8_t *values, uint32_t size)
{
	return bus_rd((uint8_t)(p->address >> 1), index, values, size) == 0 ? 0 : 255;
}

uint8_t WrMulti(VL53L5CX_Platform *p, uint16_t index, uint8_t *values, uint32_t size)
{
	return bus_wr((uint8_t)(p->address >> 1), index, values, size) == 0 ? 0 : 255;
}

uint8_t RdByte(VL53L5CX_Platform *p, uint16_t index, uint8_t *value)
{
	return RdMulti(p, index, value, 1);
}

uint8_t WrByte(VL53L5CX_Platform *p, uint16_t index, uint8_t value)
{
	return WrMulti(p, index, &value, 1);
}

uint8_t Reset_Sensor(VL53L5CX_Platform *p)
{
	(void)p;
	return 0;
}

/* Reverses the bytes of each 32-bit word (big-endian device words to this little-endian host). */
void SwapBuffer(uint8_t *buffer, uint16_t size)
{
	for (uint32_t i = 0; i + 3 < size; i += 4) {
		uint8_t a = buffer[i], b = buffer[i + 1];
		buffer[i] = buffer[i + 3];
		buffer[i + 1] = buffer[i + 2];
		buffer[i + 2] = b;
		buffer[i + 3] = a;
	}
}

uint8_t WaitMs(VL53L5CX_Platform *p, uint32_t ms)
{
	(void)p;
	waited_ms += ms;
	return 0;
}

/* ST's buffers, defined by vl53l5cx_buffers.h inside vl53l5cx_api.c. */
extern const uint8_t VL53L5CX_FIRMWARE[];
extern const uint8_t VL53L5CX_DEFAULT_CONFIGURATION[];
extern const uint8_t VL53L5CX_DEFAULT_XTALK[];
extern const uint8_t VL53L5CX_GET_NVM_CMD[];

void depthor_st_buffers(const uint8_t **fw, const uint8_t **cfg, const uint8_t **xtalk,
			const uint8_t **nvm)
{
	*fw = VL53L5CX_FIRMWARE;
	*cfg = VL53L5CX_DEFAULT_CONFIGURATION;
	*xtalk = VL53L5CX_DEFAULT_XTALK;
	*nvm = VL53L5CX_GET_NVM_CMD;
}

struct depthor_st_frame {
	int16_t distance_mm[64];
	uint16_t range_sigma_mm[64];
	uint32_t signal_per_spad[64];
	uint32_t ambient_per_spad[64];
	uint8_t target_status[64];
	uint8_t nb_target_detected[64];
	int8_t silicon_temp_degc;
};

/* Runs is_alive, init, set_resolution, set_ranging_frequency_hz, set_integration_time_ms,
 * set_ranging_mode, start_ranging, then per frame check_data_ready (until ready, at most
 * 1000 polls) and get_ranging_data, then stop_ranging. Returns 0, or 1000 * step + ST status
 * of the first failing call. */
int depthor_st_run(depthor_rd_fn rd, depthor_wr_fn wr, depthor_frame_fn on_frame,
		   uint8_t resolution, uint8_t freq_hz, uint32_t integration_ms, uint8_t mode,
		   uint32_t frames, struct depthor_st_frame *out, uint64_t *ms)
{
	static VL53L5CX_Configuration dev;
	static VL53L5CX_ResultsData res;
	uint8_t st, alive = 0, ready;

	bus_rd = rd;
	bus_wr = wr;
	waited_ms = 0;
	memset(&dev, 0, sizeof dev);
	dev.platform.address = VL53L5CX_DEFAULT_I2C_ADDRESS;

	if ((st = vl53l5cx_is_alive(&dev, &alive)) != 0 || !alive)
		return 1000 + (st ? st : 254);
	if ((st = vl53l5cx_init(&dev)) != 0)
		return 2000 + st;
	if ((st = vl53l5cx_set_resolution(&dev, resolution)) != 0)
		return 3000 + st;
	if ((st = vl53l5cx_set_ranging_frequency_hz(&dev, freq_hz)) != 0)
		return 4000 + st;
	if ((st = vl53l5cx_set_integration_time_ms(&dev, integration_ms)) != 0)
		return 5000 + st;
	if ((st = vl53l5cx_set_ranging_mode(&dev, mode)) != 0)
		return 6000 + st;
	if ((st = vl53l5cx_start_ranging(&dev)) != 0)
		return 7000 + st;
	for (uint32_t f = 0; f < frames; f++) {
		on_frame(f);
		ready = 0;
		for (int poll = 0; !ready; poll++) {
			if (poll == 1000)
				return 8000 + 254;
			if ((st = vl53l5cx_check_data_ready(&dev, &ready)) != 0)
				return 8000 + st;
		}
		memset(&res, 0, sizeof res);
		if ((st = vl53l5cx_get_ranging_data(&dev, &res)) != 0)
			return 9000 + st;
		memcpy(out[f].distance_mm, res.distance_mm, sizeof res.distance_mm);
		memcpy(out[f].range_sigma_mm, res.range_sigma_mm, sizeof res.range_sigma_mm);
		memcpy(out[f].signal_per_spad, res.signal_per_spad, sizeof res.signal_per_spad);
		memcpy(out[f].ambient_per_spad, res.ambient_per_spad, sizeof res.ambient_per_spad);
		memcpy(out[f].target_status, res.target_status, sizeof res.target_status);
		memcpy(out[f].nb_target_detected, res.nb_target_detected,
		       sizeof res.nb_target_detected);
		out[f].silicon_temp_degc = res.silicon_temp_degc;
	}
	if ((st = vl53l5cx_stop_ranging(&dev)) != 0)
		return 10000 + st;
	*ms = waited_ms;
	return 0;
}
