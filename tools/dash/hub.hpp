#pragma once
// torque-dash's web side: an HTTP + WebSocket server (CivetWeb, loopback by default) with
//   GET /                 the dashboard page (www/index.html, dash.js, dash.css)
//   GET /lib/chart.js     Chart.js from Debian's libjs-chart.js (/usr/share/javascript/chart.js)
//   GET /api/snapshot     the dashboard model as JSON (what a new page gets first)
//   GET /api/methods      the method registry (ids, names, labels, domain, in_cycle) as JSON
//   WS  /ws               the dashboard stream: a snapshot, then deltas every --period
//   WS  /                 the Foxglove WebSocket protocol (subprotocol foxglove.websocket.v1)
// Threads: the DDS thread calls on_sample() (model update + Foxglove queues; short lock, never a socket
// write); a sender thread writes every client's queue; CivetWeb's own threads accept and read. A client
// that does not read fast enough loses messages (counted; its queue is bounded), never the DDS thread's time.
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
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
  int period_ms = 100;                  ///< dashboard delta period
  std::size_t queue_bytes = 32u << 20;  ///< per-client send queue bound
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
  };
  [[nodiscard]] Stats stats();

  // CivetWeb callbacks (public for the C trampolines).
  int on_http(mg_connection* conn);
  void on_ws_ready(mg_connection* conn, bool foxglove);
  int on_ws_data(mg_connection* conn, int flags, const char* data, std::size_t len);
  void on_ws_close(const mg_connection* conn);

 private:
  struct Out {
    bool binary = false;
    std::string bytes;
  };
  struct Client {
    bool foxglove = false;
    Cursor cursor;
    foxglove::Subscriptions subs;
    std::deque<Out> queue;
    std::size_t queued_bytes = 0;
    std::uint64_t dropped = 0;
  };
  void push(Client& c, Out o);  ///< q_mu_ held
  void sender_loop();
  HubOptions o_;
  dds::DdsSettings settings_;
  Model model_;
  mg_context* ctx_ = nullptr;
  int port_ = 0;
  std::string error_;
  std::mutex conn_mu_;  ///< held while writing to connections and while a connection closes
  std::mutex q_mu_;     ///< model, clients, queues (short holds)
  std::condition_variable cv_;
  std::map<const mg_connection*, Client> clients_;
  std::thread sender_;
  std::atomic<bool> stop_{false};
  Stats stats_;                         ///< q_mu_ (but messages_sent: sent_)
  std::atomic<std::uint64_t> sent_{0};  ///< written by the sender thread only
};

}  // namespace torqued::dash
