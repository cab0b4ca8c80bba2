#pragma once
// torque-dash's web side: an HTTP + WebSocket server (CivetWeb, loopback by default) with
//   GET /                 the dashboard page (www/index.html, dash.js, dash.css)
//   GET /lib/chart.js     Chart.js from Debian's libjs-chart.js (/usr/share/javascript/chart.js)
//   GET /api/snapshot     the dashboard model as JSON (what a new page gets first)
//   GET /api/methods      the method registry (ids, names, labels, domain, in_cycle) as JSON
//   WS  /ws               the dashboard stream: a snapshot, then deltas every --period
//   WS  /                 the Foxglove WebSocket protocol (subprotocol foxglove.websocket.v1)
//   GET /api/clients      each WebSocket client's queued, sent and dropped message counts as JSON
// Threads: the DDS thread calls on_sample() (model update + Foxglove queues; short lock, never a socket
// write); each WebSocket client has a writer thread of its own that drains its queue, so a client that does
// not read blocks only its own writer; a ticker thread queues the dashboard deltas and expires silent
// engines; CivetWeb's own threads accept and read. A client that does not read fast enough loses its oldest
// messages (its queue is bounded in bytes and messages; the drops are counted per client and in total),
// never the DDS thread's time nor another client's. Clients and subscriptions are capped; an HTTP peer that
// holds a connection without completing its request is cut after request_timeout_ms.
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "dash_model.hpp"
#include "foxglove.hpp"
#include "qos.hpp"
#include "sample.hpp"

struct mg_context;
struct mg_connection;

namespace torqued::dash {

struct HubOptions {
  std::string listen = "127.0.0.1:8080";  ///< CivetWeb listening_ports syntax (address:port)
  std::string www_dir;                    ///< directory of index.html, dash.js, dash.css
  std::string js_dir = "/usr/share/javascript";
  int period_ms = 100;                 ///< dashboard delta period
  std::size_t queue_bytes = 4u << 20;  ///< per-client send queue bound (oldest dropped beyond it)
  std::size_t queue_messages = 8192;   ///< per-client send queue bound in messages
  int max_clients = 32;                ///< WebSocket clients at once (more are refused at the handshake)
  std::size_t max_subscriptions = 64;  ///< Foxglove subscriptions per client (more: a status error)
  int engine_expiry_ms = 10000;        ///< an engine id silent this long leaves the dashboard
  int request_timeout_ms = 2000;       ///< HTTP: whole request head, and each write to a peer
};

class Hub {
 public:
  Hub(HubOptions o, dds::DdsSettings settings, Model model);
  ~Hub();
  Hub(const Hub&) = delete;
  Hub& operator=(const Hub&) = delete;
  /// Starts the server; false with error() when it could not listen.
  bool start();
  [[nodiscard]] const std::string& error() const noexcept { return error_; }
  /// The port actually bound (for --listen 127.0.0.1:0).
  [[nodiscard]] int port() const noexcept { return port_; }
  void on_sample(const dds::AnySample& s, std::uint64_t receive_time_ns);
  void stop();

  struct Stats {
    std::uint64_t clients_total = 0, messages_sent = 0, messages_dropped = 0, unplaced = 0;
    std::uint64_t clients_refused = 0, subscriptions_refused = 0, engines_expired = 0;
  };
  [[nodiscard]] Stats stats();
  /// One line per connected WebSocket client: kind, queued messages, sent, dropped (JSON array).
  [[nodiscard]] std::string clients_json();

  // CivetWeb callbacks (public for the C trampolines).
  int on_http(mg_connection* conn);
  int on_ws_connect();
  void on_ws_ready(mg_connection* conn, bool foxglove);
  int on_ws_data(mg_connection* conn, int flags, const char* data, std::size_t len);
  void on_ws_close(const mg_connection* conn);

 private:
  struct Out {
    bool binary = false;
    std::string bytes;
  };
  struct Client {
    mg_connection* conn = nullptr;
    bool foxglove = false;
    Cursor cursor;
    foxglove::Subscriptions subs;
    std::deque<Out> queue;
    std::size_t queued_bytes = 0;
    std::uint64_t dropped = 0, sent = 0;
    bool closing = false;        ///< set by on_ws_close / a failed write: the writer ends
    std::condition_variable cv;  ///< q_mu_: queue not empty, or closing
    std::thread writer;
  };
  void push(Client& c, Out o);  ///< q_mu_ held
  void ticker_loop();
  void writer_loop(Client& c);
  void expire_engines(std::uint64_t now_ns);  ///< q_mu_ held
  HubOptions o_;
  dds::DdsSettings settings_;
  Model model_;
  mg_context* ctx_ = nullptr;
  int port_ = 0;
  std::string error_;
  std::mutex q_mu_;  ///< model, clients, queues (short holds; never held while writing to a socket)
  std::condition_variable cv_;
  std::map<const mg_connection*, std::unique_ptr<Client>> clients_;
  std::map<std::uint16_t, std::uint64_t> engine_seen_ns_;  ///< q_mu_: receive time of each engine's newest
  std::thread ticker_;
  std::atomic<bool> stop_{false};
  std::atomic<int> ws_clients_{0};      ///< accepted WebSocket handshakes not yet closed
  Stats stats_;                         ///< q_mu_ (but messages_sent: sent_)
  std::atomic<std::uint64_t> sent_{0};  ///< written by the writer threads
};

}  // namespace torqued::dash
