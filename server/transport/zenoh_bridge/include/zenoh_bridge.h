/* C ABI of the hapticloth zenoh bridge (server/transport/zenoh_bridge/src/lib.rs).
 *
 * Every handle is owned by the caller and freed by its own close/undeclare function. Functions
 * that can fail return NULL or -1 and leave a message for hz_last_error (per thread).
 * Callbacks run on zenoh's threads: they must return quickly and must not throw. */
#ifndef HAPTICLOTH_ZENOH_BRIDGE_H
#define HAPTICLOTH_ZENOH_BRIDGE_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct HzSession HzSession;
typedef struct HzPublisher HzPublisher;
typedef struct HzSubscriber HzSubscriber;
typedef struct HzQueryable HzQueryable;
typedef struct HzQuery HzQuery;

/* Payload bytes, the sample's key expression (not NUL-terminated), the context pointer.
 * Pointers are valid only during the call. */
typedef void (*HzSampleCallback)(const uint8_t* data, size_t len, const char* key,
                                 size_t key_len, void* ctx);
/* Reply with hz_query_reply during the call. */
typedef void (*HzQueryCallback)(const HzQuery* query, const char* key, size_t key_len,
                                void* ctx);

/* Copies the calling thread's last error (NUL-terminated, truncated to cap); returns its
 * full length. */
size_t hz_last_error(char* buf, size_t cap);

HzSession* hz_open_json5(const char* json5);
HzSession* hz_open_file(const char* path);
void hz_close(HzSession* s);

/* Puts are dropped, never blocked, under congestion. */
HzPublisher* hz_declare_publisher(const HzSession* s, const char* key);
/* 1 if at least one subscriber matches the publisher's key expression. */
int32_t hz_publisher_matching(const HzPublisher* p);
int32_t hz_put(const HzPublisher* p, const uint8_t* data, size_t len);
void hz_undeclare_publisher(HzPublisher* p);

HzSubscriber* hz_declare_subscriber(const HzSession* s, const char* key, HzSampleCallback cb,
                                    void* ctx);
/* When it returns, no callback is running or will run. */
void hz_undeclare_subscriber(HzSubscriber* sub);

HzQueryable* hz_declare_queryable(const HzSession* s, const char* key, HzQueryCallback cb,
                                  void* ctx);
/* Replies on the queryable's own (concrete) key expression. */
int32_t hz_query_reply(const HzQuery* query, const uint8_t* data, size_t len);
void hz_undeclare_queryable(HzQueryable* q);

/* Queries `selector`, calls cb for every successful reply on the calling thread, and returns
 * the number of replies (or -1) once all arrived or timeout_ms passed. */
int32_t hz_get(const HzSession* s, const char* selector, uint64_t timeout_ms, HzSampleCallback cb,
               void* ctx);

#ifdef __cplusplus
}
#endif

#endif
