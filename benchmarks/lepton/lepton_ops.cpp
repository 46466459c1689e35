// Operation counts of an OpenMM custom-force energy expression as Lepton (OpenMM's expression
// library) processes it for CustomCompoundBondForce on the Reference/CPU platforms: parse (with
// ';' definitions substituted), optimize, then differentiate with respect to every particle
// coordinate x1..zN and optimize each derivative. Prints JSON: tree sizes (nodes), distinct
// subtrees (what CompiledExpression evaluates after common-subexpression elimination, through
// ExpressionProgram) and the time spent.
// Build: g++ -O2 -std=c++11 lepton_ops.cpp -I$OPENMM/include -L$OPENMM/lib -lOpenMM -Wl,-rpath,$OPENMM/lib
#include "lepton/ParsedExpression.h"
#include "lepton/Parser.h"
#include "lepton/ExpressionProgram.h"
#include <chrono>
#include <cstdlib>
#include <iostream>
#include <iterator>
#include <string>

using namespace Lepton;

static long nodes(const ExpressionTreeNode& n) {
    long c = 1;
    for (const auto& ch : n.getChildren()) c += nodes(ch);
    return c;
}

int main(int argc, char** argv) {
    int nparticles = argc > 1 ? std::atoi(argv[1]) : 6;
    std::string expr((std::istreambuf_iterator<char>(std::cin)), std::istreambuf_iterator<char>());
    auto t0 = std::chrono::steady_clock::now();
    ParsedExpression e = Parser::parse(expr).optimize();
    long energy_nodes = nodes(e.getRootNode());
    long energy_ops = e.createProgram().getNumOperations();
    long deriv_nodes = 0, deriv_ops = 0;
    for (int p = 1; p <= nparticles; p++)
        for (const char* c : {"x", "y", "z"}) {
            ParsedExpression d = e.differentiate(std::string(c) + std::to_string(p)).optimize();
            deriv_nodes += nodes(d.getRootNode());
            deriv_ops += d.createProgram().getNumOperations();
        }
    double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::cout << "{\"energy_tree_nodes\": " << energy_nodes << ", \"energy_program_ops\": " << energy_ops
              << ", \"derivative_tree_nodes\": " << deriv_nodes << ", \"derivative_program_ops\": " << deriv_ops
              << ", \"seconds\": " << secs << "}" << std::endl;
    return 0;
}
