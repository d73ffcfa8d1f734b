// host.cpp: the C++ host example (Linux x86-64, or aarch64 under qemu-aarch64): runs the
// recorded frames of a replay image (firmware-sim/images/*.dri) through libdepthor_ffi and
// prints the same per-frame hash lines as the Rust host and the firmware.
//
// Build (x86-64; see README "Use it from C"; the g++ command is one line):
//   cargo build -p depthor-ffi --release
//   gcc -std=c99 -O2 -Iffi/include -c firmware-sim/c/replay.c -o replay.o
//   g++ -std=c++17 -Wall -Wextra -Werror -pedantic -Iffi/include -Ifirmware-sim/c
//       ffi/examples/host.cpp replay.o target/release/libdepthor_ffi.a
//       -lgcc_s -lutil -lrt -lpthread -lm -ldl -lc -o depthor-host-cpp
// Run:
//   ./depthor-host-cpp models/mcu_lite/depthor.dblob firmware-sim/images/default.dri
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>
#include <vector>

#include "depthor.h"
#include "replay.h"

namespace {

std::vector<std::uint8_t> read_file(const char *path) {
    std::ifstream f(path, std::ios::binary);
    if (!f) throw std::runtime_error(std::string("cannot read ") + path);
    return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

// The engine memory and arena, owned together; the blob must outlive it.
class Engine {
  public:
    Engine(const std::vector<std::uint8_t> &blob, std::uint32_t height, std::uint32_t width)
        : memory_(depthor_engine_size() / sizeof(std::uint64_t) + 1) {
        std::size_t need = 0;
        check(depthor_arena_bytes(blob.data(), blob.size(), height, width, &need));
        arena_.resize(need);
        check(depthor_engine_init(get(), blob.data(), blob.size(), arena_.data(), arena_.size(),
                                  height, width));
    }
    depthor_engine *get() { return reinterpret_cast<depthor_engine *>(memory_.data()); }

    static void check(std::int32_t status) {
        if (status != DEPTHOR_OK) throw std::runtime_error(depthor_status_message(status));
    }

  private:
    std::vector<std::uint64_t> memory_;  // 8-byte aligned, >= depthor_engine_align()
    std::vector<std::uint8_t> arena_;
};

}  // namespace

int main(int argc, char **argv) {
    if (argc != 3) {
        std::fprintf(stderr, "usage: %s BLOB IMAGE\n", argv[0]);
        return 2;
    }
    try {
        const auto blob = read_file(argv[1]);
        const auto image = read_file(argv[2]);
        replay_image img{};
        if (int code = replay_parse(&img, image.data(), image.size())) {
            std::printf("ERROR %d: replay image\n", code);
            return code;
        }
        Engine engine(blob, img.height, img.width);
        std::vector<float> zones(std::size_t(img.rows) * img.cols);
        std::vector<float> depth(std::size_t(img.height) * img.width);
        const replay_workspace ws{zones.data(), zones.size(), depth.data(), depth.size(),
                                  nullptr, nullptr};
        char line[160];
        for (std::uint32_t f = 0; f < img.frames; ++f) {
            std::int32_t status = DEPTHOR_OK;
            if (int code = replay_process(&img, f, engine.get(), &ws, line, sizeof line, &status)) {
                std::printf("ERROR %d: %s\n", code, depthor_status_message(status));
                return code;
            }
            std::printf("%s\n", line);
        }
    } catch (const std::exception &e) {
        std::fprintf(stderr, "error: %s\n", e.what());
        return 1;
    }
    return 0;
}
