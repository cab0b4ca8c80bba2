#include "hub.hpp"

#include <civetweb.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iterator>
#include <vector>

namespace torqued::dash {
namespace {

Hub* hub_of(const mg_connection* c) { return static_cast<Hub*>(mg_get_user_data(mg_get_context(c))); }
int http_cb(mg_connection* c, void*) { return hub_of(c)->on_http(c); }
int ws_connect_cb(const mg_connection* c, void*) { return hub_of(c)->on_ws_connect(); }  // 0: accept
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
  // Every WebSocket client holds a CivetWeb worker for its lifetime: max_clients of them plus 16 for HTTP
  // requests, each held at most request_timeout_ms by a peer that does not complete its request.
  const std::string threads = std::to_string(o_.max_clients + 16);
  const std::string request_timeout = std::to_string(o_.request_timeout_ms);
  const char* options[] = {"listening_ports",
                           o_.listen.c_str(),
                           "num_threads",
                           threads.c_str(),
                           "enable_websocket_ping_pong",
                           "yes",
                           "websocket_timeout_ms",
                           "5000",
                           "request_timeout_ms",
                           request_timeout.c_str(),
                           "enable_keep_alive",
                           "no",
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
  ticker_ = std::thread([this] { ticker_loop(); });
  return true;
}

void Hub::stop() {
  if (stop_.exchange(true)) return;
  cv_.notify_all();
  if (ticker_.joinable()) ticker_.join();
  // What was queued goes out first (bounded: a client that does not read is not waited for beyond 1 s).
  for (int i = 0; i < 100; ++i) {
    {
      std::lock_guard lk(q_mu_);
      bool empty = true;
      for (const auto& [conn, c] : clients_) empty = empty && (c->queue.empty() || c->closing);
      if (empty) break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  if (ctx_) mg_stop(ctx_);  // closes every connection: on_ws_close joins its writer
  ctx_ = nullptr;
  std::map<const mg_connection*, std::unique_ptr<Client>> left;  // any whose close was not reported
  {
    std::lock_guard lk(q_mu_);
    left.swap(clients_);
    for (auto& [conn, c] : left) {
      c->closing = true;
      c->cv.notify_all();
    }
  }
  for (auto& [conn, c] : left)
    if (c->writer.joinable()) c->writer.join();
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
  if (uri == "/api/clients") {
    send_text(conn, 200, "application/json", clients_json());
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

int Hub::on_ws_connect() {
  if (ws_clients_.fetch_add(1) >= o_.max_clients) {
    ws_clients_.fetch_sub(1);
    std::lock_guard lk(q_mu_);
    ++stats_.clients_refused;
    return 1;  // refused at the handshake
  }
  return 0;
}

void Hub::on_ws_ready(mg_connection* conn, bool fox) {
  std::lock_guard lk(q_mu_);
  auto& slot = clients_[conn];
  slot = std::make_unique<Client>();
  Client& c = *slot;
  c.conn = conn;
  c.foxglove = fox;
  ++stats_.clients_total;
  if (fox) {
    push(c, Out{false, foxglove::server_info("torque-dash", std::to_string(::getpid()))});
    push(c, Out{false, foxglove::advertise(settings_)});
  }
  c.writer = std::thread([this, &c] { writer_loop(c); });
}

int Hub::on_ws_data(mg_connection* conn, int flags, const char* data, std::size_t len) {
  const int opcode = flags & 0x0f;
  if (opcode == MG_WEBSOCKET_OPCODE_CONNECTION_CLOSE) return 0;
  if (opcode != MG_WEBSOCKET_OPCODE_TEXT) return 1;
  std::lock_guard lk(q_mu_);
  const auto it = clients_.find(conn);
  if (it == clients_.end() || !it->second->foxglove) return 1;  // the dashboard page sends nothing we need
  Client& c = *it->second;
  std::string err = c.subs.apply(std::string_view(data, len));
  if (c.subs.by_id.size() > o_.max_subscriptions) {  // keep the first max_subscriptions ids
    std::size_t n = 0;
    for (auto s = c.subs.by_id.begin(); s != c.subs.by_id.end();) {
      s = ++n > o_.max_subscriptions ? c.subs.by_id.erase(s) : std::next(s);
    }
    ++stats_.subscriptions_refused;
    err = "subscribe: at most " + std::to_string(o_.max_subscriptions) +
          " subscriptions per client (torque-dash --max-subscriptions); the others were not made";
  }
  if (!err.empty()) push(c, Out{false, foxglove::status(2, err)});
  return 1;
}

void Hub::on_ws_close(const mg_connection* conn) {
  std::unique_ptr<Client> gone;
  {
    std::lock_guard lk(q_mu_);
    const auto it = clients_.find(conn);
    if (it != clients_.end()) {
      gone = std::move(it->second);
      clients_.erase(it);
      gone->closing = true;
      gone->cv.notify_all();
    }
  }
  // The connection stays valid until this callback returns: its writer ends first (a write in progress
  // ends within request_timeout_ms).
  if (gone && gone->writer.joinable()) gone->writer.join();
  ws_clients_.fetch_sub(1);
}

/// Drop-oldest: a client that does not keep up loses its oldest queued messages (counted), never the newest.
void Hub::push(Client& c, Out o) {
  if (o.bytes.size() > o_.queue_bytes) {
    ++c.dropped;
    ++stats_.messages_dropped;
    return;
  }
  while (!c.queue.empty() &&
         (c.queued_bytes + o.bytes.size() > o_.queue_bytes || c.queue.size() >= o_.queue_messages)) {
    c.queued_bytes -= c.queue.front().bytes.size();
    c.queue.pop_front();
    ++c.dropped;
    ++stats_.messages_dropped;
  }
  c.queued_bytes += o.bytes.size();
  c.queue.push_back(std::move(o));
  c.cv.notify_one();
}

void Hub::on_sample(const dds::AnySample& s, std::uint64_t receive_time_ns) {
  std::lock_guard lk(q_mu_);
  s.visit([&](const auto& v) {
    model_.add(v);
    engine_seen_ns_[v.engine_id] = receive_time_ns;
  });
  std::string payload;
  const std::uint32_t channel = foxglove::channel_id(s.topic);
  for (auto& [conn, c] : clients_) {
    if (!c->foxglove || c->subs.by_id.empty()) continue;
    for (const std::uint32_t sub : c->subs.of_channel(channel)) {
      if (payload.empty()) payload = foxglove::sample_json(s);
      push(*c, Out{true, foxglove::message_data(sub, receive_time_ns, payload)});
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

std::string Hub::clients_json() {
  std::lock_guard lk(q_mu_);
  std::string out = "[";
  for (const auto& [conn, c] : clients_) {
    if (out.size() > 1) out += ",";
    out += std::string("{\"kind\":\"") + (c->foxglove ? "foxglove" : "dashboard") +
           "\",\"subscriptions\":" + std::to_string(c->subs.by_id.size()) +
           ",\"queued\":" + std::to_string(c->queue.size()) + ",\"sent\":" + std::to_string(c->sent) +
           ",\"dropped\":" + std::to_string(c->dropped) + "}";
  }
  return out + "]";
}

/// Engines whose samples stopped (receive time older than engine_expiry_ms) leave the model and the pages'
/// cursors: foreign or retired engine ids cannot hold the dashboard's slots forever. The pages are told too
/// ({"engines":{},"expired":[ids]}): they drop the engine from their list and charts.
void Hub::expire_engines(std::uint64_t now_ns) {
  const std::uint64_t after = static_cast<std::uint64_t>(o_.engine_expiry_ms) * 1'000'000u;
  std::string ids;
  for (auto it = engine_seen_ns_.begin(); it != engine_seen_ns_.end();) {
    if (now_ns <= it->second || now_ns - it->second <= after) {
      ++it;
      continue;
    }
    model_.forget(it->first);
    for (auto& [conn, c] : clients_) c->cursor.engines.erase(it->first);
    ++stats_.engines_expired;
    ids += (ids.empty() ? "" : ",") + std::to_string(it->first);
    it = engine_seen_ns_.erase(it);
  }
  if (ids.empty()) return;
  const std::string msg = R"({"engines":{},"expired":[)" + ids + "]}";
  for (auto& [conn, c] : clients_)
    if (!c->foxglove) push(*c, Out{false, msg});
}

/// Every period: the dashboard pages' deltas (a page whose last delta is still queued gets none: its cursor
/// stays, the next delta carries both), and engine expiry.
void Hub::ticker_loop() {
  auto next = std::chrono::steady_clock::now();
  while (!stop_) {
    std::unique_lock lk(q_mu_);
    cv_.wait_until(lk, next, [&] { return stop_.load(); });
    next += std::chrono::milliseconds(o_.period_ms);
    if (std::chrono::steady_clock::now() > next) next = std::chrono::steady_clock::now();
    for (auto& [conn, c] : clients_) {
      if (c->foxglove || !c->queue.empty()) continue;
      std::string d = model_.delta(c->cursor);
      if (!d.empty()) push(*c, Out{false, std::move(d)});
    }
    expire_engines(static_cast<std::uint64_t>(std::chrono::duration_cast<std::chrono::nanoseconds>(
                                                  std::chrono::system_clock::now().time_since_epoch())
                                                  .count()));
  }
}

/// One client's writer: blocks on this client's socket only.
void Hub::writer_loop(Client& c) {
  for (;;) {
    Out o;
    {
      std::unique_lock lk(q_mu_);
      c.cv.wait(lk, [&] { return c.closing || !c.queue.empty(); });
      if (c.closing) return;
      o = std::move(c.queue.front());
      c.queue.pop_front();
      c.queued_bytes -= o.bytes.size();
    }
    const int op = o.binary ? MG_WEBSOCKET_OPCODE_BINARY : MG_WEBSOCKET_OPCODE_TEXT;
    const int w = mg_websocket_write(c.conn, op, o.bytes.data(), o.bytes.size());
    std::lock_guard lk(q_mu_);
    if (w <= 0) {  // peer gone or not reading within request_timeout_ms: nothing more goes to it
      c.closing = true;
      return;
    }
    ++c.sent;
    sent_.fetch_add(1, std::memory_order_relaxed);
  }
}

}  // namespace torqued::dash
