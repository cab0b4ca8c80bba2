#include "hub.hpp"

#include <civetweb.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <vector>

namespace torqued::dash {
namespace {

Hub* hub_of(const mg_connection* c) { return static_cast<Hub*>(mg_get_user_data(mg_get_context(c))); }
int http_cb(mg_connection* c, void*) { return hub_of(c)->on_http(c); }
int ws_connect_cb(const mg_connection*, void*) { return 0; }  // accept
void ws_ready_dash(mg_connection* c, void*) { hub_of(c)->on_ws_ready(c, false); }
void ws_ready_fox(mg_connection* c, void*) { hub_of(c)->on_ws_ready(c, true); }
int ws_data_cb(mg_connection* c, int flags, char* data, size_t len, void*) {
  return hub_of(c)->on_ws_data(c, flags, data, len);
}
void ws_close_cb(const mg_connection* c, void*) { hub_of(c)->on_ws_close(c); }

void send_text(mg_connection* c, int status, const char* mime, const std::string& body) {
  mg_printf(c,
            "HTTP/1.1 %d %s\r\nContent-Type: %s\r\nContent-Length: %zu\r\nCache-Control: no-store\r\n"
            "Connection: close\r\n\r\n",
            status, status == 200 ? "OK" : "Not Found", mime, body.size());
  mg_write(c, body.data(), body.size());
}

}  // namespace

Hub::Hub(HubOptions o, dds::DdsSettings settings, Model model)
    : o_(std::move(o)), settings_(std::move(settings)), model_(std::move(model)) {}

Hub::~Hub() { stop(); }

bool Hub::start() {
  mg_init_library(0);
  if (!mg_check_feature(16)) {
    error_ = "this CivetWeb library was built without WebSocket support";
    return false;
  }
  const std::string period = std::to_string(o_.period_ms);
  const char* options[] = {"listening_ports",
                           o_.listen.c_str(),
                           "num_threads",
                           "16",
                           "enable_websocket_ping_pong",
                           "yes",
                           "websocket_timeout_ms",
                           "5000",
                           "request_timeout_ms",
                           "10000",
                           nullptr};
  mg_callbacks cb{};
  ctx_ = mg_start(&cb, this, options);
  if (!ctx_) {
    error_ = "cannot listen on " + o_.listen + " (address in use, or not a local address?)";
    return false;
  }
  mg_server_port ports[4]{};
  if (mg_get_server_ports(ctx_, 4, ports) > 0) port_ = ports[0].port;
  mg_set_request_handler(ctx_, "/", http_cb, nullptr);
  mg_set_websocket_handler(ctx_, "/ws", ws_connect_cb, ws_ready_dash, ws_data_cb, ws_close_cb, nullptr);
  static const char* fox_protocols[] = {foxglove::kSubprotocol};
  static mg_websocket_subprotocols fox{1, fox_protocols};
  mg_set_websocket_handler_with_subprotocols(ctx_, "/", &fox, ws_connect_cb, ws_ready_fox, ws_data_cb,
                                             ws_close_cb, nullptr);
  sender_ = std::thread([this] { sender_loop(); });
  return true;
}

void Hub::stop() {
  if (stop_.exchange(true)) return;
  cv_.notify_all();
  if (sender_.joinable()) sender_.join();
  if (ctx_) mg_stop(ctx_);
  ctx_ = nullptr;
}

int Hub::on_http(mg_connection* conn) {
  const mg_request_info* ri = mg_get_request_info(conn);
  const std::string uri = ri->local_uri ? ri->local_uri : "/";
  if (uri == "/api/snapshot") {
    Cursor fresh;
    std::string body;
    {
      std::lock_guard lk(q_mu_);
      body = model_.delta(fresh);
    }
    send_text(conn, 200, "application/json", body);
    return 200;
  }
  if (uri == "/api/methods") {
    send_text(conn, 200, "application/json", methods_json());
    return 200;
  }
  if (uri == "/favicon.ico") {
    mg_printf(conn, "HTTP/1.1 204 No Content\r\nContent-Length: 0\r\nConnection: close\r\n\r\n");
    return 204;
  }
  static const std::map<std::string, std::pair<std::string, const char*>> files = {
      {"/", {"index.html", "text/html; charset=utf-8"}},
      {"/index.html", {"index.html", "text/html; charset=utf-8"}},
      {"/dash.js", {"dash.js", "text/javascript"}},
      {"/dash.css", {"dash.css", "text/css"}}};
  std::string path;
  const char* mime = "text/plain";
  if (const auto it = files.find(uri); it != files.end()) {
    path = o_.www_dir + "/" + it->second.first;
    mime = it->second.second;
  } else if (uri == "/lib/chart.js") {
    path = o_.js_dir + "/chart.js/chart.min.js";
    mime = "text/javascript";
  }
  if (path.empty() || !std::filesystem::is_regular_file(path)) {
    send_text(conn, 404, "text/plain",
              "not found: " + uri + (path.empty() ? "" : " (" + path + " missing)") + "\n");
    return 404;
  }
  mg_send_mime_file2(conn, path.c_str(), mime, "Cache-Control: no-store\r\n");
  return 200;
}

void Hub::on_ws_ready(mg_connection* conn, bool fox) {
  std::lock_guard lk(q_mu_);
  Client& c = clients_[conn];
  c.foxglove = fox;
  ++stats_.clients_total;
  if (fox) {
    push(c, Out{false, foxglove::server_info("torque-dash", std::to_string(::getpid()))});
    push(c, Out{false, foxglove::advertise(settings_)});
  }
  cv_.notify_all();
}

int Hub::on_ws_data(mg_connection* conn, int flags, const char* data, std::size_t len) {
  const int opcode = flags & 0x0f;
  if (opcode == MG_WEBSOCKET_OPCODE_CONNECTION_CLOSE) return 0;
  if (opcode != MG_WEBSOCKET_OPCODE_TEXT) return 1;
  std::lock_guard lk(q_mu_);
  const auto it = clients_.find(conn);
  if (it == clients_.end() || !it->second.foxglove) return 1;  // the dashboard page sends nothing we need
  const std::string err = it->second.subs.apply(std::string_view(data, len));
  if (!err.empty()) push(it->second, Out{false, foxglove::status(2, err)});
  return 1;
}

void Hub::on_ws_close(const mg_connection* conn) {
  std::lock_guard wl(conn_mu_);  // not while the sender writes to it
  std::lock_guard lk(q_mu_);
  clients_.erase(conn);
}

void Hub::push(Client& c, Out o) {
  if (c.queued_bytes + o.bytes.size() > o_.queue_bytes) {
    ++c.dropped;
    ++stats_.messages_dropped;
    return;
  }
  c.queued_bytes += o.bytes.size();
  c.queue.push_back(std::move(o));
}

void Hub::on_sample(const dds::AnySample& s, std::uint64_t receive_time_ns) {
  std::lock_guard lk(q_mu_);
  s.visit([&](const auto& v) { model_.add(v); });
  std::string payload;
  const std::uint32_t channel = foxglove::channel_id(s.topic);
  for (auto& [conn, c] : clients_) {
    if (!c.foxglove || c.subs.by_id.empty()) continue;
    for (const std::uint32_t sub : c.subs.of_channel(channel)) {
      if (payload.empty()) payload = foxglove::sample_json(s);
      push(c, Out{true, foxglove::message_data(sub, receive_time_ns, payload)});
    }
  }
}

Hub::Stats Hub::stats() {
  std::lock_guard lk(q_mu_);
  Stats s = stats_;
  s.messages_sent = sent_.load(std::memory_order_relaxed);
  for (const auto& [id, v] : model_.engines()) s.unplaced += v.unplaced;
  return s;
}

void Hub::sender_loop() {
  auto next = std::chrono::steady_clock::now();
  std::vector<std::pair<mg_connection*, std::deque<Out>>> batch;
  for (bool last = false; !last;) {  // after stop(): one more pass, so what was queued goes out
    {
      std::unique_lock lk(q_mu_);
      cv_.wait_until(lk, next, [&] { return stop_.load(); });
    }
    last = stop_;
    next += std::chrono::milliseconds(o_.period_ms);
    if (std::chrono::steady_clock::now() > next) next = std::chrono::steady_clock::now();
    std::lock_guard wl(conn_mu_);
    batch.clear();
    {
      std::lock_guard lk(q_mu_);
      for (auto& [conn, c] : clients_) {
        if (!c.foxglove) {
          std::string d = model_.delta(c.cursor);
          if (!d.empty()) push(c, Out{false, std::move(d)});
        }
        if (c.queue.empty()) continue;
        batch.emplace_back(const_cast<mg_connection*>(conn), std::move(c.queue));
        c.queue.clear();
        c.queued_bytes = 0;
      }
    }
    for (auto& [conn, q] : batch) {
      for (const Out& o : q) {
        const int op = o.binary ? MG_WEBSOCKET_OPCODE_BINARY : MG_WEBSOCKET_OPCODE_TEXT;
        const int w = mg_websocket_write(conn, op, o.bytes.data(), o.bytes.size());
        if (w <= 0) {
          std::fprintf(stderr, "torque-dash: websocket write returned %d\n", w);
          break;
        }
        sent_.fetch_add(1, std::memory_order_relaxed);
      }
    }
  }
}

}  // namespace torqued::dash
