#include "photorig/daemon/service/run_queue.h"

#include <algorithm>
#include <sqlite3.h>

#include <cctype>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <stdexcept>

namespace photorig::daemon {
namespace {

std::int64_t NowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// Statement handle that finalizes itself.
class Statement {
 public:
  Statement(sqlite3* db, const std::string& sql, const std::string& path) : db_(db) {
    if (sqlite3_prepare_v2(db, sql.c_str(), -1, &stmt_, nullptr) != SQLITE_OK)
      throw std::runtime_error(path + ": " + sqlite3_errmsg(db));
  }
  ~Statement() { sqlite3_finalize(stmt_); }
  sqlite3_stmt* get() const { return stmt_; }
  void Bind(int i, const std::string& text) { sqlite3_bind_text(stmt_, i, text.c_str(), -1, SQLITE_TRANSIENT); }
  void Bind(int i, std::int64_t value) { sqlite3_bind_int64(stmt_, i, value); }

 private:
  sqlite3* db_;
  sqlite3_stmt* stmt_ = nullptr;
};

std::string Column(sqlite3_stmt* stmt, int i) {
  const unsigned char* text = sqlite3_column_text(stmt, i);
  return text ? reinterpret_cast<const char*>(text) : "";
}

}  // namespace

nlohmann::json QueuedRun::ToJson() const {
  nlohmann::json body = {{"id", id},
          {"recipe", recipe_name},
          {"state", RunStateName(state)},
          {"reason", reason},
          {"frames", frames},
          {"steps_total", steps_total},
          {"retries", retries},
          {"dropped_frames", dropped_frames},
          {"created_ns", created_ns},
          {"updated_ns", updated_ns}};
  if (!solve.is_null()) body["solve"] = solve;
  return body;
}

RunQueue::RunQueue(const std::string& path) : path_(path) {
  std::string why;
  if (!OpenWritable(&why)) OpenReadOnly(why);
}

bool RunQueue::OpenWritable(std::string* why) {
  if (sqlite3_open_v2(path_.c_str(), &db_, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_FULLMUTEX,
                      nullptr) != SQLITE_OK) {
    *why = db_ ? sqlite3_errmsg(db_) : "out of memory";
    sqlite3_close(db_);
    db_ = nullptr;
    return false;
  }
  try {
    sqlite3_busy_timeout(db_, 5000);
    Exec("PRAGMA journal_mode=WAL");
    Exec("PRAGMA synchronous=FULL");
    Exec(
        "CREATE TABLE IF NOT EXISTS runs (seq INTEGER PRIMARY KEY AUTOINCREMENT, id TEXT UNIQUE NOT NULL, "
        "recipe_name TEXT NOT NULL, state TEXT NOT NULL, reason TEXT NOT NULL DEFAULT '', "
        "frames INTEGER NOT NULL DEFAULT 0, steps_total INTEGER NOT NULL DEFAULT 0, "
        "retries INTEGER NOT NULL DEFAULT 0, dropped_frames INTEGER NOT NULL DEFAULT 0, "
        "created_ns INTEGER NOT NULL, updated_ns INTEGER NOT NULL, solve TEXT NOT NULL DEFAULT '')");
    // Queues made before runs carried their solve stages gain the column.
    bool has_solve = false;
    {
      Statement columns(db_, "PRAGMA table_info(runs)", path_);
      while (sqlite3_step(columns.get()) == SQLITE_ROW) has_solve |= Column(columns.get(), 1) == "solve";
    }
    if (!has_solve) Exec("ALTER TABLE runs ADD COLUMN solve TEXT NOT NULL DEFAULT ''");
  } catch (const std::exception& e) {
    *why = e.what();
    sqlite3_close(db_);
    db_ = nullptr;
    return false;
  }
  read_only_reason_.clear();
  return true;
}

void RunQueue::OpenReadOnly(const std::string& why_not_writable) {
  // A queue never written (a new data root on a full disk) holds no run:
  // it is read as empty until it can be created.
  std::error_code error;
  const auto size = std::filesystem::file_size(path_, error);
  if (error || size == 0) {
    read_only_reason_ = "the run queue " + path_ + " cannot be created: " + why_not_writable +
                        " (is the data disk full? it is created once there is room)";
    return;
  }
  // immutable: SQLite reads the file as it stands, without the write-ahead
  // log's index it cannot create on a full disk (changes still in the log
  // after a crash show once the queue is writable again).
  std::string uri = "file:";
  for (char c : path_) {
    if (c == '%' || c == '?' || c == '#') {
      char escaped[4];
      std::snprintf(escaped, sizeof(escaped), "%%%02X", static_cast<unsigned char>(c));
      uri += escaped;
    } else {
      uri += c;
    }
  }
  uri += "?immutable=1";
  const bool opened = sqlite3_open_v2(uri.c_str(), &db_, SQLITE_OPEN_READONLY | SQLITE_OPEN_URI | SQLITE_OPEN_FULLMUTEX,
                                      nullptr) == SQLITE_OK &&
                      sqlite3_exec(db_, "SELECT count(*) FROM runs", nullptr, nullptr, nullptr) == SQLITE_OK;
  if (!opened) {
    sqlite3_close(db_);
    db_ = nullptr;
    throw std::runtime_error("cannot open the run queue " + path_ + ": " + why_not_writable);
  }
  read_only_reason_ = "the run queue " + path_ + " is read-only: " + why_not_writable +
                      " (is the data disk full? it becomes writable once there is room)";
}

void RunQueue::MakeWritable() {
  if (read_only_reason_.empty()) return;
  sqlite3_close(db_);
  db_ = nullptr;
  std::string why;
  if (OpenWritable(&why)) return;
  OpenReadOnly(why);
  throw std::runtime_error(read_only_reason_);
}

std::string RunQueue::ReadOnlyReason() {
  std::lock_guard lock(mutex_);
  try {
    MakeWritable();
  } catch (const std::exception&) {
    // Still read-only: the reason says why.
  }
  return read_only_reason_;
}

RunQueue::~RunQueue() { sqlite3_close(db_); }

void RunQueue::Exec(const std::string& sql) const {
  char* error = nullptr;
  if (sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &error) != SQLITE_OK) {
    const std::string message = error ? error : "unknown error";
    sqlite3_free(error);
    throw std::runtime_error(path_ + ": " + message);
  }
}

QueuedRun RunQueue::Add(const std::string& recipe_name, int steps_total,
                        const std::function<void(const QueuedRun&)>& prepare) {
  std::lock_guard lock(mutex_);
  MakeWritable();
  // Ids double as directory names: keep [A-Za-z0-9_-] of the name only.
  std::string safe;
  for (char c : recipe_name)
    if (std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_') safe += c;
  if (safe.empty()) safe = "run";
  safe = safe.substr(0, 48);
  QueuedRun run;
  run.recipe_name = recipe_name;
  run.steps_total = steps_total;
  run.created_ns = run.updated_ns = NowNs();
  Exec("BEGIN IMMEDIATE");
  try {
    Statement insert(db_,
                     "INSERT INTO runs (id, recipe_name, state, steps_total, created_ns, updated_ns) VALUES "
                     "('pending-' || hex(randomblob(8)), ?1, 'queued', ?3, ?2, ?2)",
                     path_);
    insert.Bind(1, recipe_name);
    insert.Bind(2, run.created_ns);
    insert.Bind(3, static_cast<std::int64_t>(steps_total));
    if (sqlite3_step(insert.get()) != SQLITE_DONE) throw std::runtime_error(path_ + ": " + sqlite3_errmsg(db_));
    const std::int64_t seq = sqlite3_last_insert_rowid(db_);
    char id[80];
    std::snprintf(id, sizeof(id), "%06lld-%s", static_cast<long long>(seq), safe.c_str());
    run.id = id;
    Statement name(db_, "UPDATE runs SET id = ?1 WHERE seq = ?2", path_);
    name.Bind(1, run.id);
    name.Bind(2, seq);
    if (sqlite3_step(name.get()) != SQLITE_DONE) throw std::runtime_error(path_ + ": " + sqlite3_errmsg(db_));
    if (prepare) prepare(run);
    Exec("COMMIT");
  } catch (...) {
    Exec("ROLLBACK");
    throw;
  }
  return run;
}

std::vector<QueuedRun> RunQueue::Select(const std::string& where, const std::string& text_argument,
                                        const std::string& order) const {
  std::lock_guard lock(mutex_);
  if (db_ == nullptr) return {};  // not yet created (OpenReadOnly)
  Statement select(db_,
                   "SELECT id, recipe_name, state, reason, frames, steps_total, retries, dropped_frames, created_ns, "
                   "updated_ns, solve FROM runs " +
                       where + " " + order,
                   path_);
  if (!text_argument.empty()) select.Bind(1, text_argument);
  std::vector<QueuedRun> runs;
  while (sqlite3_step(select.get()) == SQLITE_ROW) {
    QueuedRun run;
    sqlite3_stmt* s = select.get();
    run.id = Column(s, 0);
    run.recipe_name = Column(s, 1);
    run.state = RunStateFromName(Column(s, 2)).value_or(RunState::kFailed);
    run.reason = Column(s, 3);
    run.frames = sqlite3_column_int(s, 4);
    run.steps_total = sqlite3_column_int(s, 5);
    run.retries = sqlite3_column_int(s, 6);
    run.dropped_frames = sqlite3_column_int(s, 7);
    run.created_ns = sqlite3_column_int64(s, 8);
    run.updated_ns = sqlite3_column_int64(s, 9);
    if (const std::string solve = Column(s, 10); !solve.empty()) {
      run.solve = nlohmann::json::parse(solve, nullptr, /*allow_exceptions=*/false);
      if (run.solve.is_discarded()) run.solve = nullptr;  // unreadable: shown as no solve, not as an error
    }
    runs.push_back(std::move(run));
  }
  return runs;
}

std::optional<QueuedRun> RunQueue::Get(const std::string& id) const {
  auto runs = Select("WHERE id = ?1", id);
  if (runs.empty()) return std::nullopt;
  return runs.front();
}

std::vector<QueuedRun> RunQueue::List() const { return Select("", ""); }

std::vector<QueuedRun> RunQueue::Page(int limit, const std::string& before_id, bool* older) const {
  const std::string where = before_id.empty() ? "" : "WHERE seq < (SELECT seq FROM runs WHERE id = ?1)";
  // One more than asked: whether it exists says whether older runs remain.
  std::vector<QueuedRun> runs = Select(where, before_id, "ORDER BY seq DESC LIMIT " + std::to_string(limit + 1));
  *older = static_cast<int>(runs.size()) > limit;
  if (*older) runs.pop_back();
  std::reverse(runs.begin(), runs.end());
  return runs;
}

int RunQueue::CountQueued() const {
  std::lock_guard lock(mutex_);
  if (db_ == nullptr) return 0;  // not yet created (OpenReadOnly)
  Statement count(db_, "SELECT COUNT(*) FROM runs WHERE state = 'queued'", path_);
  return sqlite3_step(count.get()) == SQLITE_ROW ? sqlite3_column_int(count.get(), 0) : 0;
}

std::optional<QueuedRun> RunQueue::NextQueued() const {
  auto runs = Select("WHERE state = 'queued'", "");
  if (runs.empty()) return std::nullopt;
  return runs.front();
}

std::vector<QueuedRun> RunQueue::Unfinished() const {
  return Select("WHERE state IN ('running', 'paused', 'suspended', 'aborting', 'solving')", "");
}

void RunQueue::Update(const QueuedRun& run) {
  std::lock_guard lock(mutex_);
  MakeWritable();
  Statement update(db_,
                   "UPDATE runs SET state = ?1, reason = ?2, frames = ?3, steps_total = ?4, retries = ?5, "
                   "dropped_frames = ?6, updated_ns = ?7, solve = ?9 WHERE id = ?8",
                   path_);
  update.Bind(1, std::string(RunStateName(run.state)));
  update.Bind(2, run.reason);
  update.Bind(3, static_cast<std::int64_t>(run.frames));
  update.Bind(4, static_cast<std::int64_t>(run.steps_total));
  update.Bind(5, static_cast<std::int64_t>(run.retries));
  update.Bind(6, static_cast<std::int64_t>(run.dropped_frames));
  update.Bind(7, NowNs());
  update.Bind(8, run.id);
  update.Bind(9, run.solve.is_null() ? std::string() : run.solve.dump());
  if (sqlite3_step(update.get()) != SQLITE_DONE) throw std::runtime_error(path_ + ": " + sqlite3_errmsg(db_));
}

bool RunQueue::LeaveQueued(QueuedRun& run, RunState to, const std::string& reason) {
  std::lock_guard lock(mutex_);
  MakeWritable();
  const std::int64_t now = NowNs();
  Statement update(db_, "UPDATE runs SET state = ?1, reason = ?2, updated_ns = ?3 WHERE id = ?4 AND state = 'queued'",
                   path_);
  update.Bind(1, std::string(RunStateName(to)));
  update.Bind(2, reason);
  update.Bind(3, now);
  update.Bind(4, run.id);
  if (sqlite3_step(update.get()) != SQLITE_DONE) throw std::runtime_error(path_ + ": " + sqlite3_errmsg(db_));
  if (sqlite3_changes(db_) != 1) return false;
  run.state = to;
  run.reason = reason;
  run.updated_ns = now;
  return true;
}

}  // namespace photorig::daemon
