// A ResultWriter driven from its own thread, so writing (and compressing) field frames is off
// the solver's critical path: the solver hands over a copy of each frame and steps on. The
// queue is bounded: when the writer falls behind, write_frame() blocks (back-pressure) rather
// than holding an unbounded number of frames in memory.
//
// Order and durability are the ResultWriter's: tasks run one at a time in submission order on
// the one thread, finish() runs last and returns only once the files are durable under their
// final names. An error on the writer thread is kept and thrown by the next write_frame() or by
// finish(); the tasks after it are skipped (the file is no longer trusted). Destroying the
// object without finish() discards queued frames and removes the temporary file, as
// ResultWriter's destructor does; a process killed meanwhile leaves only result.h5.tmp.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <exception>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "solver/io/checkpoint_file.hpp"
#include "solver/io/result_file.hpp"

namespace softshock {

// One thread running submitted tasks in order, at most `capacity` waiting. The generic part of
// AsyncResultWriter (tests drive it with tasks of their own).
class OrderedWorker {
 public:
  explicit OrderedWorker(std::size_t capacity);
  ~OrderedWorker();  // drops the waiting tasks, lets a running one end, joins
  OrderedWorker(const OrderedWorker&) = delete;
  OrderedWorker& operator=(const OrderedWorker&) = delete;

  // Queues a task, blocking while `capacity` tasks wait. Throws the first exception a task
  // threw (then queues nothing): once a task failed, the later ones would build on a failure.
  void submit(std::function<void()> task);
  // Waits until every submitted task has run; throws the first exception a task threw.
  void drain();
  std::size_t capacity() const { return capacity_; }

 private:
  void loop();
  void rethrow_locked() const;

  const std::size_t capacity_;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<std::function<void()>> tasks_;
  bool running_task_ = false, stopping_ = false;
  std::exception_ptr error_;
  std::thread thread_;  // last: started once the members above exist
};

class AsyncResultWriter {
 public:
  // Creates the ResultWriter (directory, temporary file, attributes) on the calling thread, so
  // set-up errors surface at once, exactly as ResultWriter's constructor throws them; the mesh
  // datasets are the writer thread's first task (an error there reaches the next write_frame()
  // or finish(), as a frame's would).
  AsyncResultWriter(const std::string& out_dir, const Mesh& mesh, const std::string& spec_json,
                    const std::string& solver_version, std::size_t max_queued_frames = 4);
  // A run continued from a checkpoint (ResultWriter's continuation constructor, on the calling
  // thread: a missing or damaged sealed file throws here).
  AsyncResultWriter(const std::string& out_dir, const Mesh& mesh, const std::string& spec_json,
                    const std::string& solver_version,
                    const std::vector<ResultWriter::Sealed>& sealed,
                    const std::vector<double>& frame_times, std::size_t max_queued_frames = 4);
  ~AsyncResultWriter();
  AsyncResultWriter(const AsyncResultWriter&) = delete;
  AsyncResultWriter& operator=(const AsyncResultWriter&) = delete;

  // Hands the frame over (blocks only while max_queued_frames wait). Throws an earlier frame's
  // write error.
  void write_frame(FieldFrame frame);
  // Writes history, summary and attributes after every queued frame, then makes the files
  // durable (ResultWriter::finish) and returns. Throws any write error.
  void finish(History history, RunSummary summary, bool complete, std::string error);

  // A checkpoint, on the writer thread after every frame queued before it: the frames so far are
  // sealed into `segment_path` (ResultWriter::seal_segment), then `checkpoint`, its header's
  // segments (named relative to the checkpoint's folder) and frame times filled in, is written to
  // `checkpoint_path` (checkpoint_file.hpp). `done` gets the outcome there: empty, or why the
  // checkpoint was not written -- which leaves the previous one in force and the run going. An
  // error sealing the frames is the result file's: thrown by the next write_frame() or finish().
  void checkpoint(Checkpoint checkpoint, std::string segment_path, std::string checkpoint_path,
                  std::function<void(const std::string& error)> done);
  // Waits until every task queued so far has run (a checkpoint before the writer goes away).
  // Throws a write error.
  void drain() { worker_.drain(); }

  // A frame already written, for the solver to fill again in place (RunControl::spare_frame),
  // or an empty frame when none is free. At most kSpareFrames are kept.
  FieldFrame spare_frame();

  std::string h5_path() const { return h5_path_; }

 private:
  static constexpr std::size_t kSpareFrames = 2;
  std::unique_ptr<ResultWriter> writer_;
  std::string h5_path_;
  std::mutex spare_mutex_;
  std::vector<FieldFrame> spares_;
  OrderedWorker worker_;  // last: destroyed (joined) first, while what its tasks use exists
};

}  // namespace softshock
