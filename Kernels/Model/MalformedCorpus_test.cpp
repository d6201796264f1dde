// One test per failure class of the malformed-model corpus (Testing/Data/malformed, written by
// its make_corpus.py): the loader must throw a ModelError that names the file and contains the
// expected description — never crash, never accept.
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "Model/InrModel.h"

namespace inr {
namespace {

struct CorpusCase {
  std::string file, failureClass, expect;
};

std::string corpusDir() { return std::string(INR_TEST_DATA_DIR) + "/malformed"; }

std::vector<CorpusCase> loadManifest() {
  std::ifstream in(corpusDir() + "/manifest.json");
  if (!in) return {};
  const auto j = nlohmann::json::parse(in);
  std::vector<CorpusCase> out;
  for (const auto& e : j) out.push_back({e["file"], e["class"], e["expect"]});
  return out;
}

// Shown by gtest/ctest instead of the struct's bytes.
void PrintTo(const CorpusCase& c, std::ostream* os) { *os << c.file << " (" << c.failureClass << ")"; }

class MalformedCorpus : public ::testing::TestWithParam<CorpusCase> {};

TEST_P(MalformedCorpus, RejectedWithClearError) {
  const CorpusCase& c = GetParam();
  const std::string path = corpusDir() + "/" + c.file;
  try {
    InrModel::loadFile(path);
    FAIL() << c.file << " (" << c.failureClass << ") was accepted";
  } catch (const ModelError& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.rfind(path + ": ", 0), 0u) << "error does not start with the file name: " << msg;
    EXPECT_NE(msg.find(c.expect), std::string::npos) << "expected '" << c.expect << "' in: " << msg;
  }
}

std::string caseName(const ::testing::TestParamInfo<CorpusCase>& info) {
  std::string n = info.param.file.substr(0, info.param.file.find('.'));
  for (char& ch : n)
    if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
  return n;
}

INSTANTIATE_TEST_SUITE_P(Files, MalformedCorpus, ::testing::ValuesIn(loadManifest()), caseName);

TEST(MalformedCorpusManifest, CoversTheRequiredClassesAndTheControlLoads) {
  const auto cases = loadManifest();
  ASSERT_GE(cases.size(), 20u) << "manifest missing or short: " << corpusDir();
  EXPECT_NO_THROW(InrModel::loadFile(corpusDir() + "/valid_control.inr"));
}

}  // namespace
}  // namespace inr
