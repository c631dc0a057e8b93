// The sweeps' row order of the PCG solver (pcg_solver.hpp): two parts that share no block, then
// their separator, then the cluster.
#include "cloth/pcg_solver.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>
#include <string>
#include <thread>
#include <stdexcept>
#include <vector>

namespace hapticloth::cloth::pcg {

// The sweeps' row order, for two threads: the cloth's rows in two parts that share no block,
// then the separator between them, then the hubs (always in the cluster). The sweeps take
// the parts at once and the separator after them (forward) or before them (backward). The
// parts are the mesh's first and second half, less the rows of the first that reach the
// second (a grid's middle row): so the two threads' rows, and their vectors' entries, meet
// in memory at one place only (split along a diagonal instead, the two cores share cache lines
// on every mesh row, and the update is slower: docs/performance.md, 'Performance of the step').
// A mesh numbered so that this separator is large is split by levels instead
// (split_by_levels). Within a part the order is the mesh's. (Each part taken as two runs in
// turn, so that a sweep advances two chains of rows at once, makes an iteration cheaper but
// takes more iterations than that saves: BENCHMARKS.md, 'The limit'.)
void PcgSolver::sweep_order(const SymCsr& A, const std::vector<int>& hub_rows) {
  const int nb = A.n / 3;
  std::vector<char> hub(nb, 0);
  for (int h : hub_rows) hub[h] = 1;
  std::array<std::vector<int>, 3> rows;  // part 0, part 1, separator; each in the mesh's order
  int cloth = 0;
  for (int br = 0; br < nb; ++br) cloth += !hub[br];
  for (int br = 0, seen = 0; br < nb; ++br) {
    if (hub[br]) continue;
    const bool first = 2 * seen++ < cloth;
    rows[first ? 0 : 1].push_back(br);
  }
  std::vector<char> second(nb, 0);
  for (int br : rows[1]) second[br] = 1;
  std::vector<int> inner;
  for (int br : rows[0]) {
    const int o = A.rowptr[3 * br], len = A.rowptr[3 * br + 1] - o;
    bool reaches = false;
    for (int k = 0; k < len && !reaches; k += 3) reaches = second[A.col[o + k] / 3] != 0;
    (reaches ? rows[2] : inner).push_back(br);
  }
  rows[0].swap(inner);
  split_ = rows[1].empty() ? nb : rows[1].front();
  if (8 * static_cast<int>(rows[2].size()) > cloth) {
    rows = split_by_levels(A, hub);
    split_ = nb / 2;
  }
  split_ &= ~3;  // 3 split_ a multiple of 4: update's second range starts a 4-lane run
  order_.clear();
  for (int q = 0; q < 3; ++q) {
    seg_[q] = static_cast<int>(order_.size());
    order_.insert(order_.end(), rows[q].begin(), rows[q].end());
  }
  seg_[3] = static_cast<int>(order_.size());
  order_.insert(order_.end(), hub_rows.begin(), hub_rows.end());
  rank_.assign(nb, 0);
  for (int i = 0; i < nb; ++i) rank_[order_[i]] = i;
  check_parts_apart(A, hub);
}

// The two parts' sweeps run at once on two threads: a block joining them would be a data race
// (and results that depend on timing). Checked once per pattern; throws std::logic_error.
void PcgSolver::check_parts_apart(const SymCsr& A, const std::vector<char>& hub) const {
  std::vector<signed char> part(A.n / 3, -1);
  for (int q = 0; q < 2; ++q)
    for (int i = seg_[q]; i < seg_[q + 1]; ++i) part[order_[i]] = static_cast<signed char>(q);
  for (int i = seg_[0]; i < seg_[2]; ++i) {
    const int br = order_[i], o = A.rowptr[3 * br], len = A.rowptr[3 * br + 1] - o;
    for (int k = 0; k < len; k += 3) {
      const int j = A.col[o + k] / 3;
      if (!hub[j] && part[j] >= 0 && part[j] != part[br])
        throw std::logic_error("pcg: block rows " + std::to_string(br) + " and " + std::to_string(j) +
                               " join the two parts of the sweeps");
    }
  }
}

// Two parts and their separator from a breadth-first level structure (from a pseudo-
// peripheral row of each connected piece): a row's blocks reach its own level and the two
// beside it only, so the level at which the count of rows passes half parts the levels before
// it from those after it. Each in the mesh's order.
std::array<std::vector<int>, 3> PcgSolver::split_by_levels(const SymCsr& A, const std::vector<char>& hub) {
  const int nb = A.n / 3;
  std::vector<int> level(nb, -1), queue;
  queue.reserve(nb);
  auto bfs = [&](int from, int base) {  // levels from base; returns the last row reached
    queue.assign(1, from);
    level[from] = base;
    for (size_t h = 0; h < queue.size(); ++h) {
      const int br = queue[h], o = A.rowptr[3 * br], len = A.rowptr[3 * br + 1] - o;
      for (int k = 0; k < len; k += 3) {
        const int j = A.col[o + k] / 3;
        if (hub[j] || level[j] >= 0) continue;
        level[j] = level[br] + 1;
        queue.push_back(j);
      }
    }
    return queue.back();
  };
  int levels = 0;  // each connected piece gets levels after the last one's
  for (int br = 0; br < nb; ++br) {
    if (hub[br] || level[br] >= 0) continue;
    const int far = bfs(br, levels);  // the farthest row from br starts the piece's levels
    for (int j : queue) level[j] = -1;
    bfs(far, levels);
    for (int j : queue) levels = std::max(levels, level[j] + 1);
  }
  std::vector<int> count(levels + 1, 0);
  int cloth = 0;
  for (int br = 0; br < nb; ++br)
    if (!hub[br]) ++count[level[br]], ++cloth;
  int mid = 0;
  for (int below = 0; mid < levels; ++mid) {
    below += count[mid];
    if (2 * below >= cloth) break;
  }
  std::array<std::vector<int>, 3> rows;
  for (int br = 0; br < nb; ++br)
    if (!hub[br]) rows[level[br] < mid ? 0 : level[br] > mid ? 1 : 2].push_back(br);
  return rows;
}

}  // namespace hapticloth::cloth::pcg
