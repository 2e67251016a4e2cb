// Reverse-mode automatic differentiation: a Wengert list recorded while a function runs on Var
// scalars, then swept backwards to accumulate adjoints.
//
// Memory: nodes live in one contiguous arena of fixed-size records, two parent indices and the
// two partial derivatives computed when the node is recorded (24 bytes, no callbacks, no per-node
// allocation), so the backward sweep is a tight loop. Reset() forgets the nodes but keeps the
// arena: a tape reused across evaluations allocates nothing once it has reached its working size.
//
// Node 0 is a sink standing for "a constant": constants have index 0, unary nodes point their
// second parent at it, and whatever the sweep accumulates there is never read. Recording thus
// never branches on how many parents an operation has.
//
// Cheap cases record less: operations on constants only record nothing, adding or subtracting a
// double shares the operand's node (the derivative is unchanged), and the dot product of a
// constant vector with three Vars records two fused nodes instead of five.
#pragma once

#include <algorithm>
#include <cassert>
#include <compare>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "photorig/solvers/autodiff/scalar.h"

namespace photorig::solvers::autodiff {

class Tape;

// A scalar whose operations are recorded on a Tape: its value and the node it is an output of.
// A Var built from a double (or default-constructed) is a constant: it belongs to no tape. A Var
// stays valid until its tape is Reset() or destroyed.
class Var {
 public:
  Var() = default;
  explicit Var(double value) : value_(value) {}

  double value() const { return value_; }
  bool is_constant() const { return tape_ == nullptr; }

  Var& operator+=(const Var& y);
  Var& operator-=(const Var& y);
  Var& operator*=(const Var& y);
  Var& operator/=(const Var& y);
  Var& operator+=(double s);
  Var& operator-=(double s);
  Var& operator*=(double s);
  Var& operator/=(double s);

 private:
  friend class Tape;
  Var(double value, std::uint32_t index, Tape* tape) : value_(value), index_(index), tape_(tape) {}

  double value_ = 0.0;
  std::uint32_t index_ = 0;
  Tape* tape_ = nullptr;
};

PHOTORIG_AUTODIFF_INLINE double ValueOf(const Var& x) { return x.value(); }

}  // namespace photorig::solvers::autodiff

namespace Eigen {

template <>
struct NumTraits<photorig::solvers::autodiff::Var>
    : photorig::solvers::autodiff::internal::DoubleNumTraits<photorig::solvers::autodiff::Var> {
  enum {
    ReadCost = 2,
    AddCost = 4,
    MulCost = 4,
  };
};

template <typename BinaryOp>
struct ScalarBinaryOpTraits<photorig::solvers::autodiff::Var, double, BinaryOp> {
  using ReturnType = photorig::solvers::autodiff::Var;
};
template <typename BinaryOp>
struct ScalarBinaryOpTraits<double, photorig::solvers::autodiff::Var, BinaryOp> {
  using ReturnType = photorig::solvers::autodiff::Var;
};

}  // namespace Eigen

namespace photorig::solvers::autodiff {

// The most nodes a tape can index: node indices are 32-bit.
inline constexpr std::size_t kMaxTapeNodes = std::numeric_limits<std::uint32_t>::max();

struct TapeOptions {
  // Nodes reserved up front (24 bytes each), in [1, max_nodes]. The Blinn-Phong least-squares
  // loss records about 11 nodes per light; the arena doubles when full. Default 4096.
  std::size_t initial_capacity = 4096;
  // The most nodes one recording may hold, the constant sink included, in [1, kMaxTapeNodes]. A
  // recording that needs more fails (Tape::ok()) rather than grow past it. Default kMaxTapeNodes.
  std::size_t max_nodes = kMaxTapeNodes;

  bool IsValid(std::string* why) const {
    auto fail = [why](std::string reason) {
      if (why) *why = std::move(reason);
      return false;
    };
    if (!(max_nodes >= 1 && max_nodes <= kMaxTapeNodes))
      return fail("max_nodes must be in [1, 2^32 - 1] (node indices are 32-bit), got " + std::to_string(max_nodes));
    if (!(initial_capacity >= 1 && initial_capacity <= max_nodes))
      return fail("initial_capacity must be in [1, max_nodes = " + std::to_string(max_nodes) + "], got " +
                  std::to_string(initial_capacity));
    return true;
  }
};

class Tape {
 public:
  using Options = TapeOptions;

  // Options that fail IsValid leave a tape that records nothing: ok() is false and error() says why.
  explicit Tape(const Options& options = Options()) {
    const bool valid = options.IsValid(&options_error_);
    capacity_ = valid ? options.initial_capacity : 1;  // room for the constant sink alone
    max_nodes_ = valid ? options.max_nodes : 1;
    nodes_.reset(new Node[capacity_]);
    adjoints_.reserve(capacity_);
    Reset();
  }
  // Vars point at their tape, so a tape stays where it was created.
  Tape(const Tape&) = delete;
  Tape& operator=(const Tape&) = delete;

  // Forgets every recorded node (Vars recorded so far become invalid) and keeps the memory; a
  // tape that was full records again.
  void Reset() {
    nodes_[0] = Node{{0.0, 0.0}, {0, 0}};
    size_ = 1;
    full_ = false;
  }

  // False when the options were invalid, or when the recording since the last Reset() needed more
  // than max_nodes nodes: the operations past that point recorded nothing (their results are
  // constants), so the derivatives it gives are wrong. ReverseJacobian checks it.
  bool ok() const { return options_error_.empty() && !full_; }
  // Why the tape is not ok(); empty when it is.
  std::string error() const {
    if (!options_error_.empty()) return "invalid TapeOptions: " + options_error_;
    if (full_) return "the recording needed more than max_nodes = " + std::to_string(max_nodes_) + " nodes";
    return {};
  }

  // A new independent input.
  Var Variable(double value) { return Push(value, 0, 0.0, 0, 0.0); }

  // Sweeps from `output` back to the start; afterwards Adjoint(x) = d output / d x for every Var
  // x recorded on this tape. Costs O(nodes recorded before output); call once per output for a
  // Jacobian. Nodes whose adjoint is zero are skipped, so an infinite partial (sqrt at 0) only
  // reaches inputs when some derivative actually flows through it.
  void Backward(const Var& output) {
    adjoints_.assign(size_, 0.0);
    if (output.tape_ != this) {
      return;  // A constant output: every derivative is zero.
    }
    adjoints_[output.index_] = 1.0;
    for (std::size_t i = output.index_; i > 0; --i) {
      const double adjoint = adjoints_[i];
      if (adjoint == 0.0) {
        continue;
      }
      const Node& node = nodes_[i];
      adjoints_[node.parent[0]] += node.partial[0] * adjoint;
      adjoints_[node.parent[1]] += node.partial[1] * adjoint;
    }
  }

  // d output / d x after Backward(output); 0 for constants and for Vars of other tapes. Meant for
  // inputs; for an intermediate Var it is the adjoint of its node, which a Var shifted by a
  // constant shares with its operand.
  double Adjoint(const Var& x) const {
    if (x.tape_ != this) {
      return 0.0;
    }
    assert(x.index_ < adjoints_.size() && "Adjoint() before Backward()");
    return adjoints_[x.index_];
  }

  // Nodes recorded, counting the constant sink.
  std::size_t size() const { return size_; }
  std::size_t capacity() const { return capacity_; }

  // The recording primitives behind every Var operation, and the way to add an elementary
  // function whose partial derivatives are known in closed form: a node with value `value` and
  // partial derivatives d_x (and d_y) w.r.t. its operands. Nothing is recorded when all operands
  // are constants.
  PHOTORIG_AUTODIFF_INLINE static Var Record(double value, const Var& x, double d_x) {
    if (x.tape_ == nullptr) {
      return Var(value);
    }
    return x.tape_->Push(value, x.index_, d_x, 0, 0.0);
  }
  PHOTORIG_AUTODIFF_INLINE static Var Record(double value, const Var& x, double d_x, const Var& y,
                                             double d_y) {
    Tape* tape = x.tape_ != nullptr ? x.tape_ : y.tape_;
    if (tape == nullptr) {
      return Var(value);
    }
    assert((x.tape_ == nullptr || y.tape_ == nullptr || x.tape_ == y.tape_) &&
           "operands recorded on different tapes");
    return tape->Push(value, x.index_, d_x, y.index_, d_y);
  }

  // x + s: same node, shifted value.
  PHOTORIG_AUTODIFF_INLINE static Var Shifted(const Var& x, double s) {
    return Var(x.value_ + s, x.index_, x.tape_);
  }

  // condition ? a : b, field by field. This compiles to conditional moves; copying a whole,
  // freshly written Var instead stalls store-to-load forwarding and made max() the single most
  // expensive operation of the Blinn-Phong recording.
  PHOTORIG_AUTODIFF_INLINE static Var Select(bool condition, const Var& a, const Var& b) {
    return Var(condition ? a.value_ : b.value_, condition ? a.index_ : b.index_,
               condition ? a.tape_ : b.tape_);
  }

 private:
  struct Node {
    double partial[2];
    std::uint32_t parent[2];
  };

  PHOTORIG_AUTODIFF_INLINE Var Push(double value, std::uint32_t parent0, double partial0,
                                    std::uint32_t parent1, double partial1) {
    if (size_ == capacity_) [[unlikely]] {
      if (!Grow()) {
        return Var(value);  // Full: a constant, and ok() is false until Reset().
      }
    }
    nodes_[size_] = Node{{partial0, partial1}, {parent0, parent1}};
    return Var(value, static_cast<std::uint32_t>(size_++), this);
  }

  // Doubles the arena up to max_nodes; amortised O(1) per node, and never again once the tape is
  // warm. False, marking the tape full, when it already holds max_nodes.
  [[gnu::noinline]] bool Grow() {
    if (capacity_ >= max_nodes_) {
      full_ = true;
      return false;
    }
    const std::size_t capacity = std::min(2 * capacity_, max_nodes_);
    std::unique_ptr<Node[]> nodes(new Node[capacity]);
    std::copy(nodes_.get(), nodes_.get() + size_, nodes.get());
    nodes_ = std::move(nodes);
    capacity_ = capacity;
    return true;
  }

  std::unique_ptr<Node[]> nodes_;
  std::size_t size_ = 0;
  std::size_t capacity_ = 0;
  std::size_t max_nodes_ = kMaxTapeNodes;
  bool full_ = false;
  std::string options_error_;  // empty when the options were valid
  std::vector<double> adjoints_;
};

namespace internal {

PHOTORIG_AUTODIFF_INLINE Var Apply(const UnaryRule& rule, const Var& x) {
  return Tape::Record(rule.value, x, rule.d_x);
}

PHOTORIG_AUTODIFF_INLINE Var Apply(const BinaryRule& rule, const Var& x, const Var& y) {
  return Tape::Record(rule.value, x, rule.d_x, y, rule.d_y);
}

}  // namespace internal

PHOTORIG_AUTODIFF_INLINE Var operator+(const Var& x) { return x; }
PHOTORIG_AUTODIFF_INLINE Var operator-(const Var& x) { return Tape::Record(-x.value(), x, -1.0); }

PHOTORIG_AUTODIFF_INLINE Var operator+(const Var& x, const Var& y) {
  return Tape::Record(x.value() + y.value(), x, 1.0, y, 1.0);
}
PHOTORIG_AUTODIFF_INLINE Var operator-(const Var& x, const Var& y) {
  return Tape::Record(x.value() - y.value(), x, 1.0, y, -1.0);
}
PHOTORIG_AUTODIFF_INLINE Var operator*(const Var& x, const Var& y) {
  return Tape::Record(x.value() * y.value(), x, y.value(), y, x.value());
}
PHOTORIG_AUTODIFF_INLINE Var operator/(const Var& x, const Var& y) {
  const double inverse = 1.0 / y.value();
  const double quotient = x.value() / y.value();
  return Tape::Record(quotient, x, inverse, y, -quotient * inverse);
}

// Shifting by a constant leaves every derivative unchanged, so the result shares x's node and
// nothing is recorded.
PHOTORIG_AUTODIFF_INLINE Var operator+(const Var& x, double s) { return Tape::Shifted(x, s); }
PHOTORIG_AUTODIFF_INLINE Var operator+(double s, const Var& x) { return Tape::Shifted(x, s); }
PHOTORIG_AUTODIFF_INLINE Var operator-(const Var& x, double s) { return Tape::Shifted(x, -s); }
PHOTORIG_AUTODIFF_INLINE Var operator-(double s, const Var& x) {
  return Tape::Record(s - x.value(), x, -1.0);
}
PHOTORIG_AUTODIFF_INLINE Var operator*(const Var& x, double s) {
  return Tape::Record(x.value() * s, x, s);
}
PHOTORIG_AUTODIFF_INLINE Var operator*(double s, const Var& x) {
  return Tape::Record(s * x.value(), x, s);
}
PHOTORIG_AUTODIFF_INLINE Var operator/(const Var& x, double s) {
  return Tape::Record(x.value() / s, x, 1.0 / s);
}
PHOTORIG_AUTODIFF_INLINE Var operator/(double s, const Var& x) {
  const double quotient = s / x.value();
  return Tape::Record(quotient, x, -quotient / x.value());
}

PHOTORIG_AUTODIFF_INLINE Var& Var::operator+=(const Var& y) { return *this = *this + y; }
PHOTORIG_AUTODIFF_INLINE Var& Var::operator-=(const Var& y) { return *this = *this - y; }
PHOTORIG_AUTODIFF_INLINE Var& Var::operator*=(const Var& y) { return *this = *this * y; }
PHOTORIG_AUTODIFF_INLINE Var& Var::operator/=(const Var& y) { return *this = *this / y; }
PHOTORIG_AUTODIFF_INLINE Var& Var::operator+=(double s) { return *this = *this + s; }
PHOTORIG_AUTODIFF_INLINE Var& Var::operator-=(double s) { return *this = *this - s; }
PHOTORIG_AUTODIFF_INLINE Var& Var::operator*=(double s) { return *this = *this * s; }
PHOTORIG_AUTODIFF_INLINE Var& Var::operator/=(double s) { return *this = *this / s; }

// Comparisons look at the value only, so control flow follows the double evaluation.
PHOTORIG_AUTODIFF_INLINE bool operator==(const Var& x, const Var& y) {
  return x.value() == y.value();
}
PHOTORIG_AUTODIFF_INLINE std::partial_ordering operator<=>(const Var& x, const Var& y) {
  return x.value() <=> y.value();
}
PHOTORIG_AUTODIFF_INLINE bool operator==(const Var& x, double s) { return x.value() == s; }
PHOTORIG_AUTODIFF_INLINE std::partial_ordering operator<=>(const Var& x, double s) {
  return x.value() <=> s;
}

// The other elementary functions are scalar.h's.
PHOTORIG_AUTODIFF_INLINE Var pow(double x, const Var& y) {
  const internal::BinaryRule rule = internal::Pow(x, y.value());
  return Tape::Record(rule.value, y, rule.d_y);
}

// w . v for a constant w as two fused nodes, (w0 v0 + w1 v1) then (+ w2 v2), instead of the
// five (three products, two sums) of the generic expression in vector.h.
PHOTORIG_AUTODIFF_INLINE Var Dot(const Eigen::Vector3d& w, const Eigen::Matrix<Var, 3, 1>& v) {
  const Var partial =
      Tape::Record(w[0] * v[0].value() + w[1] * v[1].value(), v[0], w[0], v[1], w[1]);
  return Tape::Record(partial.value() + w[2] * v[2].value(), partial, 1.0, v[2], w[2]);
}

// Selections record nothing; ties resolve as for Dual (dual.h): max/min return the first
// argument, clamp returns x.
PHOTORIG_AUTODIFF_INLINE Var max(const Var& x, const Var& y) { return Tape::Select(x < y, y, x); }
PHOTORIG_AUTODIFF_INLINE Var min(const Var& x, const Var& y) { return Tape::Select(y < x, y, x); }
PHOTORIG_AUTODIFF_INLINE Var clamp(const Var& x, const Var& lo, const Var& hi) {
  return Tape::Select(x < lo, lo, Tape::Select(hi < x, hi, x));
}

}  // namespace photorig::solvers::autodiff
