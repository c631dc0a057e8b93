/* C ABI over the Foxglove SDK (server/transport/zenoh_bridge/src/foxglove_sink.rs): a context
 * with a WebSocket server (live view) and/or an MCAP writer, and the channels /cloth,
 * /fingertips, /haptics, /loop, /events, /tactile and /tactile/pins. Log times are ns since the Unix epoch. One thread
 * calls a handle. Failures return NULL or -1 and leave a message for hz_last_error. */
#ifndef HAPTICLOTH_FOXGLOVE_BRIDGE_H
#define HAPTICLOTH_FOXGLOVE_BRIDGE_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct HfSink HfSink;

/* Channels, for hf_wants. */
enum { HF_CLOTH = 0, HF_FINGERTIPS = 1, HF_HAPTICS = 2, HF_LOOP = 3, HF_EVENTS = 4, HF_TACTILE = 5, HF_TACTILE_PINS = 6 };
/* JSON channels, for hf_declare_json and hf_json. */
enum { HF_JSON_HAPTICS = 0, HF_JSON_LOOP = 1, HF_JSON_TACTILE = 2 };

/* ws_host NULL: no WebSocket server (port 0: any free port); mcap_path NULL: no recording (an
 * existing file is an error). frame: the frame id of every scene entity. */
HfSink* hf_open(const char* ws_host, uint16_t ws_port, const char* mcap_path,
                const char* server_name, const char* frame);
int32_t hf_declare_json(HfSink* s, int32_t which, const char* schema_name, const char* schema);
uint16_t hf_port(const HfSink* s);
int32_t hf_wants(const HfSink* s, int32_t channel);
int32_t hf_cloth(HfSink* s, uint64_t log_time_ns, const float* xyz, const float* rgba,
                 uint32_t num_vertices, const uint32_t* triangles, uint32_t num_triangles);
int32_t hf_fingertips(HfSink* s, uint64_t log_time_ns, uint32_t fingers, const float* centres,
                      const float* forces, const uint8_t* contact, double radius,
                      double metres_per_newton);
int32_t hf_json(HfSink* s, int32_t which, uint64_t log_time_ns, const uint8_t* json, size_t len);
/* /tactile/pins: a mono8 image, width bytes a row. */
int32_t hf_pins(HfSink* s, uint64_t log_time_ns, uint32_t width, uint32_t height, const uint8_t* grey);
int32_t hf_event(HfSink* s, uint64_t log_time_ns, int32_t level, const char* kind,
                 const char* text);
/* Stops the server, finishes the MCAP file, frees the handle. */
int32_t hf_close(HfSink* s);

#ifdef __cplusplus
}
#endif

#endif
