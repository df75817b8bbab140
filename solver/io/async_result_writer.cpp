#include "solver/io/async_result_writer.hpp"

#include <filesystem>
#include <tuple>
#include <utility>

namespace softshock {

OrderedWorker::OrderedWorker(std::size_t capacity)
    : capacity_(capacity < 1 ? 1 : capacity), thread_([this] { loop(); }) {}

OrderedWorker::~OrderedWorker() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
    tasks_.clear();
  }
  changed_.notify_all();
  thread_.join();
}

void OrderedWorker::rethrow_locked() const {
  if (error_) std::rethrow_exception(error_);
}

void OrderedWorker::submit(std::function<void()> task) {
  std::unique_lock<std::mutex> lock(mutex_);
  changed_.wait(lock, [&] { return error_ || tasks_.size() < capacity_; });
  rethrow_locked();
  tasks_.push_back(std::move(task));
  changed_.notify_all();
}

void OrderedWorker::drain() {
  std::unique_lock<std::mutex> lock(mutex_);
  changed_.wait(lock, [&] { return error_ || (tasks_.empty() && !running_task_); });
  rethrow_locked();
}

void OrderedWorker::loop() {
  std::unique_lock<std::mutex> lock(mutex_);
  while (true) {
    changed_.wait(lock, [&] { return stopping_ || !tasks_.empty(); });
    if (stopping_) return;
    std::function<void()> task = std::move(tasks_.front());
    tasks_.pop_front();
    running_task_ = true;
    lock.unlock();
    std::exception_ptr failure;
    try {
      task();
    } catch (...) {
      failure = std::current_exception();
    }
    task = nullptr;  // release what it captured (a frame) before taking the lock
    lock.lock();
    running_task_ = false;
    if (failure && !error_) {
      error_ = failure;
      tasks_.clear();  // built on a failed write: skipped
    }
    changed_.notify_all();
  }
}

AsyncResultWriter::AsyncResultWriter(const std::string& out_dir, const Mesh& mesh,
                                     const std::string& spec_json,
                                     const std::string& solver_version,
                                     std::size_t max_queued_frames)
    : writer_(std::make_unique<ResultWriter>(out_dir, mesh, spec_json, solver_version,
                                             ResultWriter::MeshWrite::kLater)),
      h5_path_(writer_->h5_path()),
      worker_(max_queued_frames) {
  // The mesh datasets (~10 ms at 16.5k elements, measured) are the writer thread's first task,
  // from a copy: the caller's mesh may go before the writer does.
  ResultWriter* writer = writer_.get();
  auto copy = std::make_shared<const Mesh>(mesh);
  worker_.submit([writer, copy] { writer->write_mesh(*copy); });
}

AsyncResultWriter::AsyncResultWriter(const std::string& out_dir, const Mesh& mesh,
                                     const std::string& spec_json,
                                     const std::string& solver_version,
                                     const std::vector<ResultWriter::Sealed>& sealed,
                                     const std::vector<double>& frame_times,
                                     std::size_t max_queued_frames)
    : writer_(std::make_unique<ResultWriter>(out_dir, mesh, spec_json, solver_version, sealed,
                                             frame_times)),
      h5_path_(writer_->h5_path()),
      worker_(max_queued_frames) {}

AsyncResultWriter::~AsyncResultWriter() = default;

void AsyncResultWriter::checkpoint(Checkpoint checkpoint, std::string segment_path,
                                   std::string checkpoint_path,
                                   std::function<void(const std::string& error)> done) {
  auto owned = std::make_shared<Checkpoint>(std::move(checkpoint));
  worker_.submit([this, owned, segment = std::move(segment_path), path = std::move(checkpoint_path),
                  done = std::move(done)] {
    writer_->seal_segment(segment);  // throws: the result file's error
    std::string error;
    try {
      namespace fs = std::filesystem;
      const fs::path folder = fs::absolute(path).parent_path();
      auto& header = owned->header;
      header.segments.clear();
      for (const auto& s : writer_->sealed())
        header.segments.push_back(
            {fs::absolute(s.path).lexically_relative(folder).string(), s.frames});
      header.frame_times = writer_->frame_times();
      write_checkpoint(path, *owned);
    } catch (const std::exception& e) {
      error = e.what();
    }
    if (done) done(error);
  });
}

void AsyncResultWriter::write_frame(FieldFrame frame) {
  // std::function needs a copyable callable: the frame travels in a shared_ptr. Once written it
  // becomes a spare for the solver's next frame.
  auto owned = std::make_shared<FieldFrame>(std::move(frame));
  worker_.submit([this, owned] {
    writer_->write_frame(*owned);
    std::lock_guard<std::mutex> lock(spare_mutex_);
    if (spares_.size() < kSpareFrames) spares_.push_back(std::move(*owned));
  });
}

FieldFrame AsyncResultWriter::spare_frame() {
  std::lock_guard<std::mutex> lock(spare_mutex_);
  if (spares_.empty()) return {};
  FieldFrame spare = std::move(spares_.back());
  spares_.pop_back();
  return spare;
}

void AsyncResultWriter::finish(History history, RunSummary summary, bool complete,
                               std::string error) {
  ResultWriter* writer = writer_.get();
  auto args = std::make_shared<std::tuple<History, RunSummary, std::string>>(
      std::move(history), std::move(summary), std::move(error));
  worker_.submit([writer, args, complete] {
    writer->finish(std::get<0>(*args), std::get<1>(*args), complete, std::get<2>(*args));
  });
  worker_.drain();
}

}  // namespace softshock
