// dataset.yaml (io/dataset_io.h), then images.csv with the same bytes: arbitrary text.
#include "fuzz/fuzz_util.h"
#include "io/dataset_io.h"
#include "io/util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text = waymark::fuzz::Text(data, size);
  waymark::ReadWarnings warnings;
  try {
    const waymark::DatasetConfig config = waymark::ParseDatasetYaml(text, "dataset.yaml", &warnings);
    const std::string again = waymark::FormatDatasetYaml(config);
    waymark::ParseDatasetYaml(again, "again.yaml");
  } catch (const waymark::FormatError&) {
  }
  try {
    const std::vector<std::string> cameras = {"cam0", "cam1"};
    waymark::ParseImagesCsv(text, "images.csv", &cameras);
  } catch (const waymark::FormatError&) {
  }
  return 0;
}
