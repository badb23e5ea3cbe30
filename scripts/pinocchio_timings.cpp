// Native (C++) per-call timings of Pinocchio on the same URDF and states as
// `examples/timings.rs`, printed as one JSON line. Built and run by scripts/compare_pinocchio.py:
//
//   pinocchio_timings MODEL.bin STATES.csv REPS NAME
//
// MODEL.bin is the Pinocchio model the Python script built from the URDF (fingers locked with
// buildReducedModel), written with Model.saveToBinary, so both sides time the very same model.
// STATES.csv has columns q_<joint>, qd_<joint>, qdd_<joint>, tau_<joint> (mapped by joint name).
// Each function is timed as the median over REPS of one pass over all states, divided by the
// number of states, as Pinocchio's own benchmark/timings.cpp does with its PINOCCHIO_PROFILE loop.

#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>
#include <pinocchio/algorithm/model.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/multibody.hpp>
#include <pinocchio/serialization.hpp>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace pin = pinocchio;

struct State
{
  Eigen::VectorXd q, v, a, tau;
};

static std::vector<std::string> split(const std::string & s, char sep)
{
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, sep))
    out.push_back(item);
  return out;
}

// reads the states CSV into Pinocchio's configuration layout, mapping columns by joint name
static std::vector<State> read_states(const std::string & path, const pin::Model & model)
{
  std::ifstream f(path);
  if (!f)
    throw std::runtime_error(path + ": cannot read");
  std::string line;
  std::getline(f, line);
  std::map<std::string, size_t> col;
  auto header = split(line, ',');
  for (size_t i = 0; i < header.size(); ++i)
    col[header[i]] = i;
  auto find = [&](const std::string & name) -> long {
    auto it = col.find(name);
    return it == col.end() ? -1 : long(it->second);
  };
  std::vector<State> states;
  while (std::getline(f, line))
  {
    if (line.empty())
      continue;
    auto cells = split(line, ',');
    State s{pin::neutral(model), Eigen::VectorXd::Zero(model.nv), Eigen::VectorXd::Zero(model.nv),
            Eigen::VectorXd::Zero(model.nv)};
    for (pin::JointIndex j = 1; j < (pin::JointIndex)model.njoints; ++j)
    {
      const std::string & name = model.names[j];
      long cq = find("q_" + name), cv = find("qd_" + name), ca = find("qdd_" + name), ct = find("tau_" + name);
      if (cq < 0 || cv < 0)
        throw std::runtime_error(path + ": no column q_" + name + " or qd_" + name);
      const int iq = model.idx_qs[j], iv = model.idx_vs[j], nq = model.nqs[j];
      const double angle = std::stod(cells[cq]);
      if (nq == 1)
        s.q[iq] = angle;
      else if (nq == 2) // continuous joint: (cos, sin)
      {
        s.q[iq] = std::cos(angle);
        s.q[iq + 1] = std::sin(angle);
      }
      else
        throw std::runtime_error("joint " + name + " has nq = " + std::to_string(nq));
      s.v[iv] = std::stod(cells[cv]);
      if (ca >= 0)
        s.a[iv] = std::stod(cells[ca]);
      if (ct >= 0)
        s.tau[iv] = std::stod(cells[ct]);
    }
    states.push_back(s);
  }
  return states;
}

int main(int argc, char ** argv)
{
  if (argc != 5)
  {
    std::cerr << "usage: pinocchio_timings MODEL.bin STATES.csv REPS NAME\n";
    return 2;
  }
  const std::string model_path = argv[1], states_path = argv[2], name = argv[4];
  const int reps = std::stoi(argv[3]);
  // the model exactly as built in Python
  pin::Model model;
  model.loadFromBinary(model_path);
  pin::Model model_nog = model; // zero gravity: C(q, qd) qd alone
  model_nog.gravity.setZero();
  pin::Data data(model), data_nog(model_nog);
  const auto states = read_states(states_path, model);

  using Fn = std::function<void(const State &)>;
  std::vector<std::pair<std::string, Fn>> functions = {
    {"crba", [&](const State & s) { pin::crba(model, data, s.q, pin::Convention::LOCAL); }},
    {"crba_world", [&](const State & s) { pin::crba(model, data, s.q, pin::Convention::WORLD); }},
    {"computeCoriolisMatrix", [&](const State & s) { pin::computeCoriolisMatrix(model, data, s.q, s.v); }},
    {"nonLinearEffects_zero_gravity", [&](const State & s) { pin::nonLinearEffects(model_nog, data_nog, s.q, s.v); }},
    {"computeGeneralizedGravity", [&](const State & s) { pin::computeGeneralizedGravity(model, data, s.q); }},
    {"nonLinearEffects", [&](const State & s) { pin::nonLinearEffects(model, data, s.q, s.v); }},
    {"rnea", [&](const State & s) { pin::rnea(model, data, s.q, s.v, s.a); }},
    {"aba", [&](const State & s) { pin::aba(model, data, s.q, s.v, s.tau, pin::Convention::LOCAL); }},
    {"crba+computeCoriolisMatrix+computeGeneralizedGravity",
     [&](const State & s) {
       pin::crba(model, data, s.q, pin::Convention::LOCAL);
       pin::computeCoriolisMatrix(model, data, s.q, s.v);
       pin::computeGeneralizedGravity(model, data, s.q);
     }},
  };

  std::cout << "{\"robot\": \"" << name << "\", \"dof\": " << model.nv << ", \"states\": " << states.size()
            << ", \"reps\": " << reps << ", \"ns_per_call\": {";
  bool first = true;
  for (auto & [fname, f] : functions)
  {
    std::vector<double> per_call;
    // one untimed pass, then the timed repetitions
    for (int rep = 0; rep <= reps; ++rep)
    {
      auto t0 = std::chrono::steady_clock::now();
      for (const auto & s : states)
        f(s);
      auto t1 = std::chrono::steady_clock::now();
      if (rep > 0)
        per_call.push_back(std::chrono::duration<double, std::nano>(t1 - t0).count() / double(states.size()));
    }
    std::sort(per_call.begin(), per_call.end());
    const size_t n = per_call.size();
    const double median = n % 2 ? per_call[n / 2] : 0.5 * (per_call[n / 2 - 1] + per_call[n / 2]);
    std::cout << (first ? "" : ", ") << "\"" << fname << "\": " << median;
    first = false;
  }
  std::cout << "}}" << std::endl;
  return 0;
}
