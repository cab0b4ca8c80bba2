// Cyclone DDS's C library, loaded on the daemon's first DDS call instead of at process start.
//
// Linked normally, libddsc brings libcrypto, libssl and four iceoryx libraries, whose ≈ 9 000 symbol
// relocations the dynamic loader resolves before main(): 9.4 M of the 35 M instructions a `--no-dds` fast
// replay of the demo's first 0.5 s executed (callgrind; README.md, performance section). The torqued
// executable defines the DDS functions the daemon uses (the publisher, the QoS presets) as forwarders to the
// library, which it opens with dlopen() the first time one is called: a run with `--no-dds` never loads it, a
// run with DDS loads it when the publisher is created, before any real-time thread publishes. The executable
// is linked with --as-needed, so these definitions leave it without a DT_NEEDED entry for libddsc; every
// other program (torque-echo, torque-dash, the tests) links the library as before.
//
// After the first call a forwarder costs one guard load and an indirect call; no lock, no allocation.
#include <dds/dds.h>
#include <dds/ddsc/dds_loan_api.h>
#include <dlfcn.h>

#include <cstdio>

#ifndef TORQUED_DDSC_SONAME
#error "TORQUED_DDSC_SONAME (the soname of Cyclone DDS's libddsc) must be defined by the build"
#endif

namespace {

/// The library's entry points, resolved once (function-local static: thread-safe initialisation).
struct Ddsc {
  decltype(&dds_create_participant) create_participant = nullptr;
  decltype(&dds_create_qos) create_qos = nullptr;
  decltype(&dds_create_topic) create_topic = nullptr;
  decltype(&dds_create_writer) create_writer = nullptr;
  decltype(&dds_delete) del = nullptr;
  decltype(&dds_delete_qos) delete_qos = nullptr;
  decltype(&dds_get_publication_matched_status) get_publication_matched_status = nullptr;
  decltype(&dds_is_loan_available) is_loan_available = nullptr;
  decltype(&dds_is_shared_memory_available) is_shared_memory_available = nullptr;
  decltype(&dds_loan_sample) loan_sample = nullptr;
  decltype(&dds_qset_data_representation) qset_data_representation = nullptr;
  decltype(&dds_qset_deadline) qset_deadline = nullptr;
  decltype(&dds_qset_durability) qset_durability = nullptr;
  decltype(&dds_qset_history) qset_history = nullptr;
  decltype(&dds_qset_liveliness) qset_liveliness = nullptr;
  decltype(&dds_qset_reliability) qset_reliability = nullptr;
  decltype(&dds_strretcode) strretcode = nullptr;
  decltype(&dds_write) write = nullptr;
};

template <class F>
void resolve(void* lib, const char* name, F& fn, bool& ok) {
  // dlsym's result is an object pointer by its signature; POSIX guarantees the conversion to a function
  // pointer.
  fn = reinterpret_cast<F>(dlsym(lib, name));  // NOLINT(cppcoreguidelines-pro-type-reinterpret-cast)
  if (fn == nullptr) ok = false;
}

Ddsc open_ddsc() {
  Ddsc d;
  void* lib = dlopen(TORQUED_DDSC_SONAME, RTLD_NOW | RTLD_LOCAL);
  if (lib == nullptr) {
    std::fprintf(stderr, "torqued: cannot load Cyclone DDS (%s): %s\n", TORQUED_DDSC_SONAME, dlerror());
    return d;
  }
  bool ok = true;
  resolve(lib, "dds_create_participant", d.create_participant, ok);
  resolve(lib, "dds_create_qos", d.create_qos, ok);
  resolve(lib, "dds_create_topic", d.create_topic, ok);
  resolve(lib, "dds_create_writer", d.create_writer, ok);
  resolve(lib, "dds_delete", d.del, ok);
  resolve(lib, "dds_delete_qos", d.delete_qos, ok);
  resolve(lib, "dds_get_publication_matched_status", d.get_publication_matched_status, ok);
  resolve(lib, "dds_is_loan_available", d.is_loan_available, ok);
  resolve(lib, "dds_is_shared_memory_available", d.is_shared_memory_available, ok);
  resolve(lib, "dds_loan_sample", d.loan_sample, ok);
  resolve(lib, "dds_qset_data_representation", d.qset_data_representation, ok);
  resolve(lib, "dds_qset_deadline", d.qset_deadline, ok);
  resolve(lib, "dds_qset_durability", d.qset_durability, ok);
  resolve(lib, "dds_qset_history", d.qset_history, ok);
  resolve(lib, "dds_qset_liveliness", d.qset_liveliness, ok);
  resolve(lib, "dds_qset_reliability", d.qset_reliability, ok);
  resolve(lib, "dds_strretcode", d.strretcode, ok);
  resolve(lib, "dds_write", d.write, ok);
  if (!ok) {
    std::fprintf(stderr, "torqued: %s lacks a function torqued uses: %s\n", TORQUED_DDSC_SONAME, dlerror());
    return Ddsc{};  // all or nothing: every call then fails as without the library
  }
  return d;
}

const Ddsc& ddsc() {
  static const Ddsc d = open_ddsc();
  return d;
}

}  // namespace

// The forwarders: without the library, entity calls return DDS_RETCODE_ERROR (a negative entity, as Cyclone
// reports a failed creation), QoS setters do nothing and dds_create_qos returns null (its users check the
// entities they create with it).
extern "C" {

dds_entity_t dds_create_participant(const dds_domainid_t domain, const dds_qos_t* qos,
                                    const dds_listener_t* listener) {
  const auto f = ddsc().create_participant;
  return f ? f(domain, qos, listener) : DDS_RETCODE_ERROR;
}

dds_qos_t* dds_create_qos(void) {
  const auto f = ddsc().create_qos;
  return f ? f() : nullptr;
}

dds_entity_t dds_create_topic(dds_entity_t participant, const dds_topic_descriptor_t* descriptor,
                              const char* name, const dds_qos_t* qos, const dds_listener_t* listener) {
  const auto f = ddsc().create_topic;
  return f ? f(participant, descriptor, name, qos, listener) : DDS_RETCODE_ERROR;
}

dds_entity_t dds_create_writer(dds_entity_t participant_or_publisher, dds_entity_t topic,
                               const dds_qos_t* qos, const dds_listener_t* listener) {
  const auto f = ddsc().create_writer;
  return f ? f(participant_or_publisher, topic, qos, listener) : DDS_RETCODE_ERROR;
}

dds_return_t dds_delete(dds_entity_t entity) {
  const auto f = ddsc().del;
  return f ? f(entity) : DDS_RETCODE_ERROR;
}

void dds_delete_qos(dds_qos_t* __restrict qos) {
  if (const auto f = ddsc().delete_qos) f(qos);
}

dds_return_t dds_get_publication_matched_status(dds_entity_t writer,
                                                dds_publication_matched_status_t* status) {
  const auto f = ddsc().get_publication_matched_status;
  return f ? f(writer, status) : DDS_RETCODE_ERROR;
}

bool dds_is_loan_available(const dds_entity_t entity) {
  const auto f = ddsc().is_loan_available;
  return f ? f(entity) : false;
}

bool dds_is_shared_memory_available(const dds_entity_t entity) {
  const auto f = ddsc().is_shared_memory_available;
  return f ? f(entity) : false;
}

dds_return_t dds_loan_sample(dds_entity_t writer, void** sample) {
  const auto f = ddsc().loan_sample;
  return f ? f(writer, sample) : DDS_RETCODE_ERROR;
}

void dds_qset_data_representation(dds_qos_t* __restrict qos, uint32_t n,
                                  const dds_data_representation_id_t* values) {
  if (const auto f = ddsc().qset_data_representation) f(qos, n, values);
}

void dds_qset_deadline(dds_qos_t* __restrict qos, dds_duration_t deadline) {
  if (const auto f = ddsc().qset_deadline) f(qos, deadline);
}

void dds_qset_durability(dds_qos_t* __restrict qos, dds_durability_kind_t kind) {
  if (const auto f = ddsc().qset_durability) f(qos, kind);
}

void dds_qset_history(dds_qos_t* __restrict qos, dds_history_kind_t kind, int32_t depth) {
  if (const auto f = ddsc().qset_history) f(qos, kind, depth);
}

void dds_qset_liveliness(dds_qos_t* __restrict qos, dds_liveliness_kind_t kind,
                         dds_duration_t lease_duration) {
  if (const auto f = ddsc().qset_liveliness) f(qos, kind, lease_duration);
}

void dds_qset_reliability(dds_qos_t* __restrict qos, dds_reliability_kind_t kind,
                          dds_duration_t max_blocking_time) {
  if (const auto f = ddsc().qset_reliability) f(qos, kind, max_blocking_time);
}

const char* dds_strretcode(dds_return_t ret) {
  const auto f = ddsc().strretcode;
  return f ? f(ret) : "Cyclone DDS library not loaded";
}

dds_return_t dds_write(dds_entity_t writer, const void* data) {
  const auto f = ddsc().write;
  return f ? f(writer, data) : DDS_RETCODE_ERROR;
}

}  // extern "C"
